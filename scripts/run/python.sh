# shellcheck shell=bash
# The Python that makes the venv: stop with advice when the PyPI ROS has no wheels for it
# (sourced by run.sh).

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
