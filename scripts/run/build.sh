# shellcheck shell=bash
# colcon build of this package (and of the message packages the environment lacks), skipped
# when nothing changed (sourced by run.sh).

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
    # Built again when a source is newer than the stamp, or one came or went (the list of
    # sources is in the stamp). What builds and tests write in the source tree is no source:
    # bytecode and numba's kernel cache (__pycache__/*.pyc, *.nbi, *.nbc beside the sources,
    # from compile_kernels), setuptools' egg-info; nor are the folders' own times, which such
    # a file changes.
    local sources
    sources=$(source_files | cksum)
    if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$sources" ] \
            && [ -z "$(source_files -newer "$stamp" | head -n 1)" ]; then
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
    printf '%s\n' "$sources" >"$stamp"
}

source_files() {
    # The package's source files, sorted (extra find tests, e.g. -newer FILE, narrow them).
    (cd "$ROOT" && find package.xml setup.py setup.cfg mover6_control sim_bridge config scripts \
        interfaces launch \( -name __pycache__ -o -name '*.egg-info' \) -prune -o -type f \
        -not -name '*.pyc' -not -name '*.nbi' -not -name '*.nbc' "$@" -print 2>/dev/null) \
        | LC_ALL=C sort
}

compile_kernels() {
    # The numba kernels (motion/timing, kinematics/ik_batch_kernel) into their on-disk cache,
    # beside the installed modules and beside the sources (the tests import those), once per
    # build: no node compiles them at its start (several seconds each; from the cache about one).
    local stamp="$WS/.kernels"
    if [ -f "$stamp" ] && [ "$stamp" -nt "$WS/.built" ]; then
        return 0
    fi
    log "compiling the kernels (numba, once per build; log: $WS/kernels.log)"
    { (cd "$WS" && python -m mover6_control.tools.compile_kernels) \
        && (cd "$ROOT" && python -m mover6_control.tools.compile_kernels); } >"$WS/kernels.log" 2>&1 || {
        tail -n 20 "$WS/kernels.log" >&2
        log "compiling the kernels failed; full log: $WS/kernels.log"
        return 1
    }
    touch "$stamp"
}
