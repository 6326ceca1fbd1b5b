#!/usr/bin/env bash
# Start the mover6_control nodes and keep them running until Ctrl-C: the stack that
# mover6_control/stack.py defines (which nodes, their parameter files and the parameters the
# options set; launch/mover6.launch.py starts the same from it). Stops all of them on exit, on
# Ctrl-C / SIGTERM, and as soon as an essential node (the arm, the driver, the controller) dies;
# a helper that dies (planner, state publisher, markers, RViz) is reported and started again
# after a back-off delay, the arm going on (mover6_control/node_roles.py).
#
# Usage: scripts/launch.sh [--hardware H] [--can-interface I] [--can-channel C] [--no-sim]
#                          [--profile P] [--jog-units U] [--limit-set L] [--log-dir DIR] [--rviz]
#                          [--namespace NS]
# scripts/launch.sh --help lists the options, their choices and defaults (python3 -m
# mover6_control.stack help), and the extra ROS arguments per node (MOVER6_CONTROLLER_ARGS ...).
#
# Needs an environment where the package is built and sourced (./run.sh launch does that).
set -uo pipefail

for arg in "$@"; do
    case "$arg" in -h | --help) exec python3 -m mover6_control.stack help ;; esac
done
# One Python process (mover6_control/tools/launch_shell.py) prints: the package's prefix; the options'
# values (checked: exit 2 with the choices) and start_stack, the nodes' start lines, from the one
# stack definition, mover6_control/stack.py; the DDS setup: on this machine (UDP on 127.0.0.1, no
# shared memory: the package's Fast DDS profile) unless the user chose their own DDS setup (robot
# network), docs/dds.md; which nodes are essential (their exit stops the stack) and which are
# helpers (started again with back-off), mover6_control/node_roles.py; the namespace, checked by
# ROS's naming rules (the TF frame prefix is the stack's).
setup=$(python3 -m mover6_control.tools.launch_shell -- "$@")
rc=$?
if [ "$rc" != 0 ]; then
    python3 -c 'import mover6_control' 2>/dev/null \
        || echo 'launch.sh: package mover6_control not found: build and source it (./run.sh launch)' >&2
    exit "$rc"
fi
eval "$setup"
if [ "$rviz" = true ] && ! command -v rviz2 >/dev/null; then
    echo 'launch.sh: --rviz: rviz2 is not installed here (it comes with a ROS 2 desktop install)' >&2
    exit 2
fi
bin="$prefix/lib/mover6_control"
ns_args=()
[ "$namespace" != / ] && ns_args=(-r "__ns:=$namespace")
share="$prefix/share/mover6_control/config"
[ -n "$log_dir" ] && mkdir -p "$log_dir"
tmp_dir=''
pids=()
names=()
declare -A cmd_of since_of restarts_of    # per node: its command line, start time, restarts
start_can_sim() {
    # The CAN-level Mover6 on a pty linked at $can_channel; wait until the link is there.
    local args=(--link "$can_channel")
    # shellcheck disable=SC2206
    args+=(${MOVER6_CAN_SIM_ARGS:-})
    if [ -n "$log_dir" ]; then
        "$bin/can_sim" "${args[@]}" > >(tee "$log_dir/can_sim.log") 2>&1 &
    else
        "$bin/can_sim" "${args[@]}" &
    fi
    pids+=($!)
    names+=(can_sim)
    echo "launch.sh: started can_sim (pid $!) on $can_channel" >&2
    for _ in $(seq 600); do
        [ -e "$can_channel" ] && return 0
        kill -0 "${pids[-1]}" 2>/dev/null || break
        sleep 0.1
    done
    echo "launch.sh: can_sim did not open $can_channel" >&2
    exit 1
}
run() {
    # run NAME: run NAME's command line (cmd_of) in the background; LAST_PID gets its pid.
    local name=$1
    if [ -n "$log_dir" ]; then
        eval "${cmd_of[$name]}"' > >(tee -a "$log_dir/$name.log") 2>&1 &'
    else
        eval "${cmd_of[$name]}"' &'
    fi
    LAST_PID=$!
    since_of[$name]=$SECONDS
}
start_command() {
    # start_command NAME COMMAND...: start a node (or RViz) and keep its command for a restart
    local name=$1
    shift
    cmd_of[$name]=$(printf '%q ' "$@")
    [ -n "$log_dir" ] && : >"$log_dir/$name.log"
    run "$name"
    pids+=("$LAST_PID")
    names+=("$name")
    echo "launch.sh: started $name (pid $LAST_PID)" >&2
}
start() {
    # start NAME EXECUTABLE [ros args...]
    local name=$1 exe=$2
    shift 2
    local params=()
    [ -f "$share/$name.yaml" ] && params=(--params-file "$share/$name.yaml")
    start_command "$name" "$bin/$exe" --ros-args "${params[@]}" "${ns_args[@]}" "$@"
}
restart() {
    # restart INDEX: start the helper pids[INDEX] again after its back-off delay (node_roles)
    local i=$1 name=${names[$1]} rc=$2
    local ran=$(( SECONDS - ${since_of[$name]} )) n delay=$RESTART_DELAY
    [ "$ran" -ge "$STEADY_RUN" ] && restarts_of[$name]=0
    n=${restarts_of[$name]:-0}
    for (( k = 0; k < n; k++ )); do
        delay=$(( 2 * delay > MAX_RESTART_DELAY ? MAX_RESTART_DELAY : 2 * delay ))
    done
    restarts_of[$name]=$(( n + 1 ))
    echo "launch.sh: $name exited (code $rc) after $ran s; a helper: the arm and the" \
         "controller go on, $name starts again in $delay s" >&2
    sleep "$delay" &
    wait $!
    run "$name"
    pids[$i]=$LAST_PID
    echo "launch.sh: started $name (pid $LAST_PID) again, restart $(( n + 1 ))" >&2
}

stopping=0
stop_all() {
    [ "$stopping" = 1 ] && return
    stopping=1
    local pid
    for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null; done
    # Give the nodes 5 s to send their last zero command and shut down, then insist.
    for _ in $(seq 50); do
        local alive=0
        for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
        [ "$alive" = 0 ] && break
        sleep 0.1
    done
    for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null; done
    wait 2>/dev/null
    [ -n "$tmp_dir" ] && rm -rf "$tmp_dir"
    echo 'launch.sh: all nodes stopped' >&2
}
trap 'stop_all; exit 130' INT
trap 'stop_all; exit 143' TERM
trap 'stop_all' EXIT

if [ "$hardware" = can-sim ] && [ -z "$can_channel" ]; then
    # The CAN-level Mover6's pty link in a fresh temporary folder; the driver opens it.
    tmp_dir=$(mktemp -d "${TMPDIR:-/tmp}/mover6-can-XXXXXX") || exit 1
    can_channel="$tmp_dir/mover6-can"
    stack=$(python3 -m mover6_control.stack shell --channel "$can_channel" -- "$@") || exit $?
    eval "$stack"
fi

start_stack

# Wait until a node exits. An essential one stops the rest (reported); a helper is reported and
# started again after its back-off delay, the others going on.
while true; do
    wait -n "${pids[@]}"
    rc=$?
    for i in "${!pids[@]}"; do
        kill -0 "${pids[$i]}" 2>/dev/null && continue
        if [[ " $HELPERS " == *" ${names[$i]} "* ]]; then
            restart "$i" "$rc"
            continue 2
        fi
        echo "launch.sh: ${names[$i]} exited (code $rc); stopping the others" >&2
        stop_all
        exit $(( rc == 0 ? 1 : rc ))
    done
done
