# shellcheck shell=bash
# What every command runs with: the user's own DDS setup noted, Python and rendering
# settings, and run.sh's log line (sourced by run.sh first).

# A DDS setup of the user's own (a robot network) is left as it is (docs/dds.md).
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
