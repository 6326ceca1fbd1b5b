#!/usr/bin/env bash
# mover6_control: the one entry point (./run.sh help prints what it does). It sets itself up on
# first use; what it installs is listed in requirements/*.txt. Each step is a small file in
# scripts/run/, sourced here in the order a command uses them:
#   environment.sh   settings every command runs with, the user's own DDS setup noted
#   requirements.sh  what pip installs (requirements/*.txt) and the stamp that skips it again
#   python.sh        the Python that makes the venv (3.11 for the PyPI ROS), or advice
#   venv.sh          the venv, made once, activated with the workspace on top
#   system_libs.sh   EGL/GL for offscreen rendering
#   browser.sh       the headless Chromium + chromedriver the console's e2e test drives
#   build.sh         colcon build, skipped when nothing changed; the numba kernels compiled
#   ensure.sh        all of the above in order, then the local DDS configuration
#   network.sh       a private network namespace (only loopback), a DDS domain of our own
#   test.sh          ./run.sh test: colcon test, namespace then host pass, results, skip budget
#   help.sh          ./run.sh help
set -eo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
absolute() { case "$1" in /*) printf '%s' "$1" ;; *) printf '%s/%s' "$PWD" "$1" ;; esac; }
# The environment and the colcon workspace (overridable: tests set up throw-away ones).
VENV=$(absolute "${MOVER6_VENV:-$ROOT/.venv}")
WS=$(absolute "${MOVER6_WS:-$ROOT/.colcon}")
PYTHON_BIN=${PYTHON:-python3}

for step in environment requirements python venv system_libs browser build ensure network test help; do
    # shellcheck disable=SC1090
    . "$ROOT/scripts/run/$step.sh"
done

cmd=${1:-help}
shift || true
case "$cmd" in
    setup)  ensure; setup_browser; log "ready (venv: $VENV, install: $WS/install)" ;;
    exec)   ensure; exec "$@" ;;
    test)   run_tests "$@" ;;
    demo)
        ensure
        in_private_netns demo "$@"
        pick_domain_id
        exec python -m mover6_control.tools.demo "$@"
        ;;
    launch) ensure; exec bash "$ROOT/scripts/launch.sh" "$@" ;;
    goal)   ensure; exec python -m mover6_control.tools.goal_cli "$@" ;;
    program) ensure; exec python -m mover6_control.tools.program_cli "$@" ;;  # docs/programs.md
    record) ensure; exec python -m mover6_control.tools.record "$@" ;;
    report) ensure; exec python -m mover6_control.tools.report "$@" ;;
    generate) ensure; exec python -m mover6_control.tools.generate "$ROOT" "$@" ;;
    first-run) ensure; exec python -m mover6_control.tools.first_run "$@" ;;   # docs/real_arm.md
    console) ensure; exec python -m mover6_control.nodes.console.node "$@" ;;  # docs/console.md
    bench)
        ensure
        in_private_netns bench "$@"
        pick_domain_id
        cd "$ROOT"          # python -m bench finds the bench package in the current directory
        exec python -m bench "$@"
        ;;
    help | -h | --help) usage ;;
    *) log "unknown command '$cmd'"; usage >&2; exit 2 ;;
esac
