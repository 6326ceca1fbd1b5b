#!/usr/bin/env bash
# Start the mover6_control nodes (the arm: sim_bridge or the CAN driver; controller, planner; the
# state publisher: /robot_description, /tf) and keep them running until Ctrl-C. Stops all of them
# on exit, on Ctrl-C / SIGTERM, and as soon as an essential node (the arm, the driver, the
# controller) dies; a helper that dies (planner, state publisher, markers, RViz) is reported and
# started again after a back-off delay, the arm going on (mover6_control/node_roles.py).
#
# Usage: scripts/launch.sh [--hardware H] [--can-interface I] [--can-channel C] [--no-sim]
#                          [--profile P] [--jog-units U] [--limit-set L] [--log-dir DIR] [--rviz]
#                          [--namespace NS] [--console]
#   --hardware H     what stands for the arm: sim (default: the MuJoCo bridge) | can-sim (the
#                    CAN-level Mover6 on a pty, can_sim, and the driver on it, enabled at start)
#                    | can (the driver on a real arm's bus; enable it with its ~/reset, ~/enable)
#   --can-interface I  driver bus with --hardware can: cpr_usb2can (default) | socketcan | pcan
#   --can-channel C  its channel: /dev/ttyUSB0 (default), can0, ...; with can-sim the pty's
#                    link (default: a fresh temporary folder's mover6-can)
#   --no-sim         do not start the MuJoCo bridge (drive a real arm's driver instead)
#   --profile P      controller profile (the planner times its prediction with it too):
#                    continuous (default) | synchronised | trapezoidal | jerk_limited | cubic |
#                    quintic | septic | sharp_trapezoid | cubic_spline | quintic_spline |
#                    bspline | multi_trapezoid
#   --jog-units U    rad_per_s (default) | fraction_of_max (vendor driver; the sim acts as it)
#   --limit-set L    joint limits of every node: within_90_deg (default) | hardware
#   --log-dir DIR    also write each node's output to DIR/<node>.log
#   --rviz           also start RViz (rviz2) with rviz/mover6.rviz: the arm, /tf, /markers
#   --console        also start the web console on http://127.0.0.1:8080 (docs/console.md)
#   --namespace NS   every node, topic, service and action under NS (a second arm: /arm2), TF
#                    frames prefixed NS/ (ROS naming rules; a malformed one is refused)
# Extra ROS arguments per node: MOVER6_SIM_ARGS, MOVER6_DRIVER_ARGS, MOVER6_CONTROLLER_ARGS,
# MOVER6_PLANNER_ARGS, MOVER6_STATE_PUBLISHER_ARGS, MOVER6_MARKERS_ARGS, e.g.
# MOVER6_CONTROLLER_ARGS="-p t_max:=2.0"; MOVER6_CAN_SIM_ARGS for can_sim's command line (e.g.
# "--home 0 0.3 0 0 0 0"). Parameter files: config/<node>.yaml.
# With the driver the controller's state_timeout is 0.5 s (the driver publishes at its 20 Hz).
# The timed threads (the controller's tick, the bridge's physics, the driver's cycle) run at
# SCHED_FIFO 50 where the system allows it (tick_priority, physics_priority, cycle_priority in
# the parameter files; without the right each node says so once and runs at normal scheduling;
# MOVER6_CONTROLLER_ARGS="-p tick_priority:=0" turns one off).
# launch/mover6.launch.py (ros2 launch) starts the same (test/unit/launch/test_launch_file.py checks).
#
# Needs an environment where the package is built and sourced (./run.sh launch does that).
set -uo pipefail

# The choices, and the defaults (the shipped parameter files' values).
PROFILES='continuous synchronised trapezoidal jerk_limited cubic quintic septic sharp_trapezoid cubic_spline quintic_spline bspline multi_trapezoid'
JOG_UNITS='rad_per_s fraction_of_max'
LIMIT_SETS='within_90_deg hardware'
HARDWARE='sim can-sim can'
hardware=sim
can_interface=cpr_usb2can
can_channel=''
with_sim=1
profile=continuous
jog_units=rad_per_s
limit_set=within_90_deg
log_dir=''
rviz=0
console=0
namespace=''
one_of() {
    # one_of OPTION VALUE CHOICES...: exit 2 unless VALUE is one of CHOICES
    local option=$1 value=$2 choice
    shift 2
    for choice in "$@"; do [ "$value" = "$choice" ] && return 0; done
    echo "launch.sh: $option must be one of: $*; got '$value'" >&2
    exit 2
}
while [ $# -gt 0 ]; do
    case "$1" in
        --no-sim) with_sim=0 ;;
        --rviz) rviz=1 ;;
        --console) console=1 ;;
        --namespace) namespace=${2:-}; shift ;;
        --profile) profile=${2:-}; shift ;;
        --jog-units) jog_units=${2:-}; shift ;;
        --limit-set) limit_set=${2:-}; shift ;;
        --log-dir) log_dir=${2:-}; shift ;;
        --hardware) hardware=${2:-}; shift ;;
        --can-interface) can_interface=${2:-}; shift ;;
        --can-channel) can_channel=${2:-}; shift ;;
        -h | --help) sed -n '2,38p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "launch.sh: unknown argument '$1'" >&2; exit 2 ;;
    esac
    shift
done
# shellcheck disable=SC2086
one_of --profile "$profile" $PROFILES
# shellcheck disable=SC2086
one_of --jog-units "$jog_units" $JOG_UNITS
# shellcheck disable=SC2086
one_of --limit-set "$limit_set" $LIMIT_SETS
# shellcheck disable=SC2086
one_of --hardware "$hardware" $HARDWARE
if [ "$hardware" != sim ]; then
    with_sim=0
    with_driver=1
    enable_on_start=false
    [ "$hardware" = can-sim ] && enable_on_start=true
    [ "$hardware" = can-sim ] && can_interface=cpr_usb2can
    [ "$hardware" = can ] && [ -z "$can_channel" ] && can_channel=/dev/ttyUSB0
    state_timeout=0.5
    cycle_driver=true     # the driver integrates set-points at its cycle: compensate in flight
else
    with_driver=0
    state_timeout=0.25
    cycle_driver=false
fi
if [ "$rviz" = 1 ] && ! command -v rviz2 >/dev/null; then
    echo 'launch.sh: --rviz: rviz2 is not installed here (it comes with a ROS 2 desktop install)' >&2
    exit 2
fi
# The simulator stands in for the vendor driver when the controller speaks its units.
sim_mode=rad_per_s
[ "$jog_units" = fraction_of_max ] && sim_mode=vendor_driver

prefix=$(python3 -c 'from ament_index_python.packages import get_package_prefix as p; print(p("mover6_control"))' 2>/dev/null) || {
    echo 'launch.sh: package mover6_control not found: build and source it (./run.sh launch)' >&2
    exit 1
}
# DDS stays on this machine (UDP on 127.0.0.1, no shared memory: the package's Fast DDS profile)
# unless the user chose their own DDS setup (robot network); README, "DDS".
dds=$(python3 -m mover6_control.nodes.runtime.local_dds env) || exit 1
eval "$dds"
bin="$prefix/lib/mover6_control"
# Which nodes are essential (their exit stops the stack) and which are helpers (started again
# with back-off): the one table, mover6_control/node_roles.py.
roles=$(python3 -m mover6_control.node_roles shell) || exit 1
eval "$roles"
# The namespace, checked by ROS's naming rules, and its TF frame prefix (/arm1 -> arm1/).
checked=$(python3 -m mover6_control.nodes.runtime.names "$namespace") || exit 2
read -r namespace tf_prefix <<<"$checked"
ns_args=()
[ "$namespace" != / ] && ns_args=(-r "__ns:=$namespace")
share="$prefix/share/mover6_control/config"
[ -n "$log_dir" ] && mkdir -p "$log_dir"

pids=()
names=()
declare -A cmd_of since_of restarts_of    # per node: its command line, start time, restarts
tmp_dir=''
start_can_sim() {
    # The CAN-level Mover6 on a pty linked at $can_channel; wait until the link is there.
    if [ -z "$can_channel" ]; then
        tmp_dir=$(mktemp -d "${TMPDIR:-/tmp}/mover6-can-XXXXXX") || exit 1
        can_channel="$tmp_dir/mover6-can"
    fi
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

# shellcheck disable=SC2086
[ "$with_sim" = 1 ] && start sim_bridge sim_bridge \
    -p "limit_set:=$limit_set" -p "mode:=$sim_mode" ${MOVER6_SIM_ARGS:-}
[ "$hardware" = can-sim ] && start_can_sim
# shellcheck disable=SC2086
[ "$with_driver" = 1 ] && start driver driver \
    -p "can_interface:=$can_interface" -p "can_channel:=$can_channel" \
    -p "jog_units:=$jog_units" -p "limit_set:=$limit_set" \
    -p "enable_on_start:=$enable_on_start" ${MOVER6_DRIVER_ARGS:-}
# shellcheck disable=SC2086
start controller controller \
    -p "profile:=$profile" -p "jog_units:=$jog_units" -p "limit_set:=$limit_set" \
    -p "state_timeout:=$state_timeout" -p "cycle_driver:=$cycle_driver" \
    ${MOVER6_CONTROLLER_ARGS:-}
# shellcheck disable=SC2086
start planner planner -p "limit_set:=$limit_set" -p "profile:=$profile" ${MOVER6_PLANNER_ARGS:-}
# /robot_description, /tf and /tf_static for RViz (robot_state_publisher's topics).
# shellcheck disable=SC2086
start state_publisher state_publisher -p "frame_prefix:='$tf_prefix'" \
    ${MOVER6_STATE_PUBLISHER_ARGS:-}
# The goal, the planned tool path, the table and the keep-out boxes on /markers.
# shellcheck disable=SC2086
start markers markers -p "frame_prefix:='$tf_prefix'" ${MOVER6_MARKERS_ARGS:-}
[ "$rviz" = 1 ] && start_command rviz2 "$(command -v rviz2)" \
    -d "$prefix/share/mover6_control/rviz/mover6.rviz"
# The web console (docs/console.md): its own options (--port, --host) in MOVER6_CONSOLE_ARGS.
# shellcheck disable=SC2086
[ "$console" = 1 ] && start_command console "$bin/console" ${MOVER6_CONSOLE_ARGS:-} \
    --ros-args "${ns_args[@]}"

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
