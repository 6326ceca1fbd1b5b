# shellcheck shell=bash
# Step of run.sh: the browser the console's e2e test drives (Debian's chromium + chromedriver).

setup_browser() {
    # The console's browser test (e2e) drives the distribution's headless Chromium: installed
    # where missing and when we may (root, apt-get), else the test says what is missing. Called
    # before a run enters its private network namespace: apt cannot reach a registry there.
    command -v chromium >/dev/null && command -v chromedriver >/dev/null && return 0
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        log "installing chromium chromium-driver (the console's browser test)"
        mkdir -p "$WS"
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            chromium chromium-driver; } >"$WS/apt.log" 2>&1 \
            || log "apt-get failed (see $WS/apt.log): the browser tests cannot run"
    else
        log 'no chromium and chromedriver, and no right to install them (not root): the browser' \
            'tests will skip (MOVER6_SKIP_BROWSER=1 accepts that; docs/testing.md)'
    fi
}
