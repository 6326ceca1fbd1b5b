# shellcheck shell=bash
# The system libraries offscreen rendering needs (sourced by run.sh).

setup_system_libs() {
    # Offscreen rendering needs EGL and GL (Debian's Mesa). Installed once, when missing and
    # when we may (root); otherwise say what to install.
    # ldconfig lives in /sbin, which a user's PATH often lacks.
    local libs
    libs=$(PATH="$PATH:/usr/sbin:/sbin" ldconfig -p 2>/dev/null || true)
    if grep -q 'libEGL.so.1' <<<"$libs" && grep -q 'libEGL_mesa.so.0' <<<"$libs"; then
        return 0
    fi
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        log "installing libegl1 libgl1 libegl-mesa0 (offscreen rendering)"
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            libegl1 libgl1 libegl-mesa0; } >"$WS/apt.log" 2>&1 \
            || log "apt-get failed (see $WS/apt.log): rendering will not work"
    else
        log "offscreen rendering needs: sudo apt-get install libegl1 libgl1 libegl-mesa0"
    fi
}
