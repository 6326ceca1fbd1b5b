#!/usr/bin/env bash
# mover6_control: the one entry point (./run.sh help prints what it does). It sets itself up on
# first use; what it installs is listed in requirements/*.txt.
set -eo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
absolute() { case "$1" in /*) printf '%s' "$1" ;; *) printf '%s/%s' "$PWD" "$1" ;; esac; }
# The environment and the colcon workspace (overridable: tests set up throw-away ones).
VENV=$(absolute "${MOVER6_VENV:-$ROOT/.venv}")
WS=$(absolute "${MOVER6_WS:-$ROOT/.colcon}")
PYTHON_BIN=${PYTHON:-python3}

usage() {
    cat <<'EOF'
mover6_control: the one entry point.

  ./run.sh demo            start the nodes headless, run the showcase (recorded), print the results
  ./run.sh test            colcon build + colcon test (pytest summary on the console)
                           (inside a private network namespace when the machine allows one)
  ./run.sh launch [args]   the three nodes in the foreground until Ctrl-C (scripts/launch.sh)
  ./run.sh goal ...        the goal CLI (./run.sh goal --help)
  ./run.sh console [--port P]  the web console on http://127.0.0.1:8080 (docs/console.md)
  ./run.sh record [-o BAG] [TOPICS]  record the stack's topics (rosbag2 MCAP) until Ctrl-C
  ./run.sh report BAG      the demo's report (plots, metrics, gif) of a recording
  ./run.sh bench [--quick] the benchmarks: tables on the console, JSON in bench/results/
  ./run.sh setup           only set up (also done on first use of any other command)
  ./run.sh exec CMD ...    run CMD inside the project environment

On a machine with a sourced ROS 2 Jazzy install it uses that install. Otherwise it makes a
project-local virtual environment (.venv) with ROS 2 Jazzy from PyPI wheels (these need
Python 3.11), builds a local control_msgs (JointJog, FollowJointTrajectory) and tf2_msgs
(TFMessage) when none is found, and builds this package with colcon into .colcon/. What it installs is listed in requirements/*.txt.
Re-running is quick and changes nothing. It works from any directory.

Environment: PYTHON  the interpreter that makes the venv (default python3)
             MOVER6_VENV, MOVER6_WS  the venv and the colcon workspace (default .venv, .colcon)
DDS: this machine only (UDP on 127.0.0.1, config/fastdds_local.xml) unless you set your own
             (ROS_AUTOMATIC_DISCOVERY_RANGE, FASTRTPS_DEFAULT_PROFILES_FILE, ...): README, "DDS".
EOF
}

# A DDS setup of the user's own (a robot network) is left as it is (README, "DDS").
USER_DDS=''
for v in ROS_AUTOMATIC_DISCOVERY_RANGE FASTRTPS_DEFAULT_PROFILES_FILE FASTDDS_DEFAULT_PROFILES_FILE \
         FASTDDS_BUILTIN_TRANSPORTS ROS_LOCALHOST_ONLY ROS_STATIC_PEERS RMW_IMPLEMENTATION MOVER6_DDS; do
    [ -n "${!v:-}" ] && USER_DDS="$USER_DDS $v"
done
export PYTHONDONTWRITEBYTECODE=1
export MPLBACKEND=Agg
# Offscreen MuJoCo rendering (demo animation, render tests) through EGL when there is no display.
[ -z "${DISPLAY:-}" ] && export MUJOCO_GL=${MUJOCO_GL:-egl}

log() { printf '[run.sh] %s\n' "$*" >&2; }

# Everything pip installs is listed in requirements/: ros.txt, build.txt and lint.txt for the
# PyPI ROS only, python.txt and test.txt (the tests' own) always. Versions are pinned where a
# newer release could change behaviour.
read_reqs() {
    # read_reqs ARRAY NAME: ARRAY gets the requirement lines of requirements/NAME.txt (comments
    # and blank lines left out).
    local file="$ROOT/requirements/$2.txt"
    [ -f "$file" ] || { log "missing $file"; exit 1; }
    mapfile -t "$1" < <(sed -e 's/#.*//' -e 's/^[[:space:]]*//' -e 's/[[:space:]]*$//' \
                            -e '/^$/d' "$file")
}
read_reqs ROS_REQS ros
read_reqs BUILD_REQS build
read_reqs LINT_REQS lint
read_reqs PY_REQS python
read_reqs TEST_REQS test

have_system_ros() {
    [ "${ROS_DISTRO:-}" = "jazzy" ] && "$PYTHON_BIN" -c 'import rclpy' >/dev/null 2>&1
}

to_install() {
    # What this path installs, into the array INSTALL: on top of a sourced ROS, only the Python
    # libraries and colcon's setuptools (its line in build.txt); otherwise everything.
    INSTALL=()
    if [ -n "${MOVER6_SYSTEM_ROS:-}" ]; then
        local r
        INSTALL=("${PY_REQS[@]}" "${TEST_REQS[@]}")
        for r in "${BUILD_REQS[@]}"; do
            case "$r" in setuptools*) INSTALL+=("$r") ;; esac
        done
    else
        INSTALL=("${ROS_REQS[@]}" "${BUILD_REQS[@]}" "${LINT_REQS[@]}" "${PY_REQS[@]}" \
                 "${TEST_REQS[@]}")
    fi
}

setup_stamp() {
    # INSTALL as to_install, and STAMP: the file that skips re-installation. It names a hash of
    # the requirement lines (a changed pin re-installs, a changed comment does not) and of the
    # path (sourced ROS or not).
    to_install
    STAMP="$VENV/.mover6_setup_$(printf '%s\n' "${INSTALL[@]}" "${MOVER6_SYSTEM_ROS:-}" \
        | sha1sum | cut -c1-12)"
}

check_python() {
    # The ROS 2 Jazzy wheels on PyPI are built for CPython 3.11 only: with another Python, pip
    # would fail minutes later deep in its log. Say what to do before making anything.
    local version
    version=$("$PYTHON_BIN" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null) \
        || version=''
    [ "$version" = 3.11 ] && return 0
    if [ -z "$version" ]; then
        log "no Python found at PYTHON=$PYTHON_BIN; ROS 2 Jazzy from PyPI needs Python 3.11."
    else
        log "$PYTHON_BIN is Python $version, but ROS 2 Jazzy from PyPI needs Python 3.11"
        log "(its wheels are built for 3.11 only)."
    fi
    if [ -n "${ROS_DISTRO:-}" ] && [ "$ROS_DISTRO" != jazzy ]; then
        log "The sourced ROS is '$ROS_DISTRO'; this package needs ROS 2 Jazzy."
    elif [ "${ROS_DISTRO:-}" = jazzy ]; then
        log "ROS_DISTRO=jazzy is set, but $PYTHON_BIN cannot import rclpy."
    fi
    log "Either install ROS 2 Jazzy and source it"
    log "(https://docs.ros.org/en/jazzy/Installation.html):"
    log "    source /opt/ros/jazzy/setup.bash && $0 ${cmd:-setup}"
    log "or make a Python 3.11 available (pyenv, uv, the deadsnakes PPA) and point PYTHON at it:"
    log "    PYTHON=python3.11 $0 ${cmd:-setup}"
    log "Nothing was installed."
    exit 1
}

activate() {
    # shellcheck disable=SC1091
    . "$VENV/bin/activate"
    if [ -z "${MOVER6_SYSTEM_ROS:-}" ]; then
        export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
        export CMAKE_PREFIX_PATH="$VENV${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
    fi
    if [ -f "$WS/install/setup.bash" ]; then
        # shellcheck disable=SC1091
        . "$WS/install/setup.bash"
    fi
}

setup_venv() {
    setup_stamp
    [ -f "$STAMP" ] && return 0
    log "setting up the Python environment in $VENV (first use; about 2 minutes)"
    if [ -n "${MOVER6_SYSTEM_ROS:-}" ]; then
        "$PYTHON_BIN" -m venv --system-site-packages "$VENV"
        pip_install "${INSTALL[@]}"
    else
        "$PYTHON_BIN" -m venv "$VENV"
        pip_install --upgrade pip
        pip_install "${INSTALL[@]}"
        fix_wheel_cmake_paths
    fi
    touch "$STAMP"
}

pip_install() {
    # pip's output goes to a log; on failure its tail is shown.
    "$VENV/bin/pip" install --disable-pip-version-check "$@" >>"$VENV/pip.log" 2>&1 || {
        grep -v '^WARNING: Location' "$VENV/pip.log" | tail -n 30 >&2
        log "pip install failed; full log: $VENV/pip.log"
        return 1
    }
}

fix_wheel_cmake_paths() {
    # The ros-jazzy wheels' CMake exports name include folders of the machine that built them
    # (/opt/python/cp311-cp311/...); CMake refuses to generate while those do not exist. Point
    # them at this interpreter's include folder and numpy's headers, inside the venv only.
    local py_inc np_inc
    py_inc=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
    np_inc=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
    local f
    for f in $(grep -rl '/opt/python/cp311-cp311' "$VENV"/share/*/cmake/ 2>/dev/null || true); do
        sed -i -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_inc#g" \
               -e "s#/opt/python/cp311-cp311/include/python3.11#$py_inc#g" "$f"
    done
}

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

setup_browser() {
    # The console's browser test (e2e) drives the distribution's headless Chromium: installed
    # where missing and when we may (root), else the test says what is missing and skips.
    command -v chromium >/dev/null && command -v chromedriver >/dev/null && return 0
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        log "installing chromium chromium-driver (the console's browser test)"
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            chromium chromium-driver; } >"$WS/apt.log" 2>&1 \
            || log "apt-get failed (see $WS/apt.log): the browser test will skip"
    fi
}

colcon_build() {
    # Build control_msgs and tf2_msgs only when the environment has none, then this package. Skipped when
    # nothing changed since the last build.
    local stamp="$WS/.built" paths=(".")
    if ! python -c 'from control_msgs.msg import JointJog' >/dev/null 2>&1 \
        || [ -d "$WS/install/control_msgs" ]; then
        paths+=("interfaces/control_msgs")
    fi
    # tf2_msgs (/tf, /tf_static) likewise: the PyPI wheels have none.
    if ! python -c 'from tf2_msgs.msg import TFMessage' >/dev/null 2>&1 \
        || [ -d "$WS/install/tf2_msgs" ]; then
        paths+=("interfaces/tf2_msgs")
    fi
    if [ -f "$stamp" ] && [ -z "$(cd "$ROOT" && find package.xml setup.py setup.cfg \
            mover6_control sim_bridge config scripts interfaces launch -newer "$stamp" \
            -not -name '*.pyc' -print -quit 2>/dev/null)" ]; then
        return 0
    fi
    log "colcon build (${paths[*]})"
    (cd "$ROOT" && colcon --log-base "$WS/log" build --base-paths "${paths[@]}" \
        --build-base "$WS/build" --install-base "$WS/install" \
        --event-handlers console_cohesion- status- summary- >"$WS/build.log" 2>&1) || {
        tail -n 40 "$WS/build.log" >&2
        log "colcon build failed; full log: $WS/build.log"
        return 1
    }
    touch "$stamp"
}

ensure() {
    if [ -z "${MOVER6_SYSTEM_ROS:-}" ] && have_system_ros; then
        export MOVER6_SYSTEM_ROS=1
        log "using the sourced ROS 2 $ROS_DISTRO install"
    fi
    setup_stamp
    # Stop before making anything when the venv would need a Python the PyPI ROS has no wheels for.
    [ -f "$STAMP" ] || [ -n "${MOVER6_SYSTEM_ROS:-}" ] || check_python
    mkdir -p "$WS"
    setup_system_libs
    setup_venv
    activate
    colcon_build
    activate
    local_dds
}

local_dds() {
    # DDS stays on this machine unless the user chose their own setup (a robot network): the
    # package's Fast DDS profile, UDP on 127.0.0.1 only, no shared memory (README, "DDS").
    local exports
    exports=$(python -m mover6_control.nodes.runtime.local_dds env) || {
        log 'cannot set up DDS (python -m mover6_control.nodes.runtime.local_dds env failed)'
        exit 1
    }
    eval "$exports"
}

private_netns() {
    # private_netns: UNSHARE gets the command that makes a private network namespace here
    # (unshare -n as root, a user namespace otherwise), or the function fails: none allowed.
    local un
    for un in 'unshare -n' 'unshare -rn'; do
        [ "$un" = 'unshare -n' ] && [ "$(id -u)" != 0 ] && continue
        # shellcheck disable=SC2086
        if $un true 2>/dev/null; then read -ra UNSHARE <<<"$un"; return 0; fi
    done
    return 1
}

in_private_netns() {
    # in_private_netns demo|bench ARGS: run ./run.sh again inside a private network namespace
    # (only loopback: nothing the nodes send can leave the machine; the package's stall-free
    # local DDS configuration applies there) when the machine allows one, the user chose no DDS
    # setup of their own and did not ask for the host network (MOVER6_NETNS=0). Returns when it
    # does not; the caller then runs on the host network (the same local configuration).
    [ "${MOVER6_NETNS:-1}" = 0 ] && return 0
    [ -n "$USER_DDS" ] && return 0
    only_loopback && return 0
    private_netns || return 0
    log "$1 inside a private network namespace (${UNSHARE[*]}): only loopback (MOVER6_NETNS=0: host)"
    unset ROS_AUTOMATIC_DISCOVERY_RANGE MOVER6_DDS FASTRTPS_DEFAULT_PROFILES_FILE
    exec "${UNSHARE[@]}" bash -c 'ip link set lo up && exec "$0" "$@"' "$ROOT/run.sh" "$@"
}

only_loopback() {
    # True when this network namespace has no interface but lo.
    [ "$(ip -o link show 2>/dev/null | awk -F': ' '{print $2}' | tr '\n' ' ')" = 'lo ' ]
}

pick_domain_id() {
    # A run of our own gets its own DDS domain unless the user chose one (0..101 is safe).
    if [ -z "${ROS_DOMAIN_ID:-}" ]; then
        export ROS_DOMAIN_ID=$(( 1 + ($$ + RANDOM) % 100 ))
    fi
}

cmd=${1:-help}
shift || true
case "$cmd" in
    setup)
        ensure
        setup_browser
        log "ready (venv: $VENV, install: $WS/install)"
        ;;
    exec)
        ensure
        exec "$@"
        ;;
    test)
        # Inside a private network namespace (only loopback) when the machine allows one: then
        # nothing a test sends can reach another process or machine, and the tests run the
        # package's local DDS configuration (test/e2e/test_local_dds.py checks that they did).
        if [ "${MOVER6_TEST_NETWORK:-}" = netns ]; then
            only_loopback || { log 'MOVER6_TEST_NETWORK=netns, but interfaces other than lo exist'; exit 1; }
            ip link set lo up
            unset ROS_AUTOMATIC_DISCOVERY_RANGE FASTRTPS_DEFAULT_PROFILES_FILE \
                FASTDDS_DEFAULT_PROFILES_FILE FASTDDS_BUILTIN_TRANSPORTS ROS_LOCALHOST_ONLY \
                ROS_STATIC_PEERS MOVER6_DDS
            ensure
        else
            # Without one: the same local configuration on the host network (loopback only),
            # unless the user chose their own (ROS_AUTOMATIC_DISCOVERY_RANGE, MOVER6_DDS=...).
            ensure
            if [ "${MOVER6_NETNS:-1}" != 0 ] && private_netns; then
                log "tests inside a private network namespace (${UNSHARE[*]}): only loopback (MOVER6_NETNS=0: host)"
                [ $# -gt 0 ] && MOVER6_TEST_NETWORK=netns exec "${UNSHARE[@]}" "$ROOT/run.sh" test "$@"
                # The whole suite: then the tests of the DDS configuration itself (marker
                # host_network) again on this machine's own network, where a user runs the
                # launchers: the local configuration keeps every socket on loopback there too.
                netns_rc=0
                MOVER6_TEST_NETWORK=netns "${UNSHARE[@]}" "$ROOT/run.sh" test || netns_rc=$?
                log 'the host_network tests again on the host network (the local configuration)'
                host_rc=0
                MOVER6_NETNS=0 "$ROOT/run.sh" test -m host_network || host_rc=$?
                log "inside the namespace: exit $netns_rc; on the host network: exit $host_rc"
                exit $(( netns_rc != 0 || host_rc != 0 ))
            fi
            if [ "${MOVER6_NETNS:-1}" = 0 ]; then
                log 'MOVER6_NETNS=0: tests on the host network (the local configuration: loopback only)'
            else
                log 'this machine allows no private network namespace: tests on the host network'
            fi
            export MOVER6_TEST_NETWORK=host
        fi
        setup_browser
        pick_domain_id
        log "tests in ROS_DOMAIN_ID=$ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-}${MOVER6_DDS:+, MOVER6_DDS=$MOVER6_DDS}"
        # Bytecode, and pytest's rewritten test modules, cached in the workspace (out of the
        # source tree): without it every run compiled every module again, a large part of the
        # unit tier's time. Python checks each source's mtime, so a cache is never stale. For
        # pytest's process only: test/conftest.py takes it from the processes the tests start.
        unset PYTHONDONTWRITEBYTECODE
        export PYTHONPYCACHEPREFIX="$WS/pycache"
        # No stale results: a run that wrote none must fail, not pass on the last one's.
        rm -rf "$WS/build/mover6_control/test_results" "$WS/build/mover6_control/pytest.xml"
        (cd "$ROOT" && colcon --log-base "$WS/log" test --base-paths . \
            --build-base "$WS/build" --install-base "$WS/install" \
            --packages-select mover6_control --event-handlers console_direct+ summary- \
            --pytest-args "$@") || true
        if [ ! -f "$WS/build/mover6_control/pytest.xml" ]; then
            log "pytest wrote no results: the test run did not happen (see $WS/log)"
            exit 1
        fi
        rc=0
        colcon test-result --test-result-base "$WS/build/mover6_control" --verbose || rc=$?
        # Skips that say so: every skipped test with its reason, by tier; a tier that skips more
        # than test/skips_allowed.json (a whole run's counts) fails the run.
        python "$ROOT/test/skip_budget.py" "$WS/build/mover6_control/pytest.xml" || rc=1
        exit "$rc"
        ;;
    demo)
        ensure
        in_private_netns demo "$@"
        pick_domain_id
        exec python -m mover6_control.tools.demo "$@"
        ;;
    launch)
        ensure
        exec bash "$ROOT/scripts/launch.sh" "$@"
        ;;
    goal)
        ensure
        exec python -m mover6_control.tools.goal_cli "$@"
        ;;
    console)
        ensure
        exec python -m mover6_control.nodes.console.console_node "$@"
        ;;
    record)
        ensure
        exec python -m mover6_control.tools.record "$@"
        ;;
    report)
        ensure
        exec python -m mover6_control.tools.report "$@"
        ;;
    bench)
        ensure
        in_private_netns bench "$@"
        pick_domain_id
        cd "$ROOT"          # python -m bench finds the bench package in the current directory
        exec python -m bench "$@"
        ;;
    help | -h | --help)
        usage
        ;;
    *)
        log "unknown command '$cmd'"
        usage >&2
        exit 2
        ;;
esac
