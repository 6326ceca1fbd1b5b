# shellcheck shell=bash
# The project venv: made once, activated with the colcon workspace on top (sourced by run.sh).

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
