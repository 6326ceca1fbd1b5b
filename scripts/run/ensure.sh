# shellcheck shell=bash
# Everything a command needs, in order: venv, system libraries, build, the compiled kernels,
# local DDS (sourced by run.sh; every command but help calls ensure).

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
    compile_kernels
    local_dds
}

local_dds() {
    # DDS stays on this machine unless the user chose their own setup (a robot network): the
    # package's Fast DDS profile, UDP on 127.0.0.1 only, no shared memory (docs/dds.md).
    local exports
    exports=$(python -m mover6_control.nodes.runtime.local_dds env) || {
        log 'cannot set up DDS (python -m mover6_control.nodes.runtime.local_dds env failed)'
        exit 1
    }
    eval "$exports"
}
