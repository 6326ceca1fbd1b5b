# shellcheck shell=bash
# What pip installs, read from requirements/*.txt, and the stamp that skips installing again
# (sourced by run.sh).

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
