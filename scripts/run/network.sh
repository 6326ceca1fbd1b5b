# shellcheck shell=bash
# The network a run uses: a private network namespace (only loopback) where the machine
# allows one, and a DDS domain of its own (sourced by run.sh).

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
