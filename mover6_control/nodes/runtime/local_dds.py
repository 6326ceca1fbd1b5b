"""
The package's "this machine only" DDS configuration, and the check that a node really got it.

Under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` rmw_fastrtps (Jazzy) always adds Fast DDS's
shared-memory transport, whose port health check holds a participant's send lock for ~1/3 s each
time a process joins the graph (eProsima/Fast-DDS#6535): every publish of the node, the
controller's tick included, stops that long. The local configuration instead is
``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` with the shipped Fast DDS profile
``config/fastdds_local.xml``: UDPv4 on 127.0.0.1 only, unicast discovery to 127.0.0.1, no
multicast, no shared memory. ``MOVER6_DDS=local`` says a node was asked for it. It is the
launchers' default on every machine (``default_environment``): nothing it sends leaves
loopback, on a host with other interfaces too. A user's own DDS variables are left as they are
(a robot network), and ``MOVER6_DDS=localhost`` selects ROS's ``LOCALHOST`` discovery (with its
shared memory and the stall) instead.

A node asked for the local configuration that did not get it refuses to start with the reason
(``shutdown.run_node`` calls ``check_environment`` before rclpy starts and makes the node with
``make_checked_node``): a profile file that Fast DDS did not load, or did not apply,
would otherwise fall back silently to multicast discovery on every interface.
"""

from __future__ import annotations

import filecmp
import os
import socket
import struct
import sys
from typing import Callable, Mapping, MutableMapping, Optional, TYPE_CHECKING, Union

from mover6_control.resources import CONFIG_DIR

if TYPE_CHECKING:      # no rclpy at import: the launchers call this before anything of ROS
    from rclpy.node import Node

MODE_ENV = 'MOVER6_DDS'
LOCAL = 'local'
LOCALHOST = 'localhost'
PROFILE = os.path.join(CONFIG_DIR, 'fastdds_local.xml')
PROFILE_ENV = 'FASTRTPS_DEFAULT_PROFILES_FILE'     # the name Fast DDS 2.x reads
RANGE_ENV = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
# Variables with which a user chooses their own DDS setup (a robot network): when any is set,
# the launchers leave DDS as the user set it.
USER_DDS_ENV = (RANGE_ENV, PROFILE_ENV, 'FASTDDS_DEFAULT_PROFILES_FILE',
                'FASTDDS_BUILTIN_TRANSPORTS', 'ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS',
                'RMW_IMPLEMENTATION', MODE_ENV)
# Set, these would change what the profile says (transports, peers, middleware).
CONFLICTING_ENV = ('FASTDDS_BUILTIN_TRANSPORTS', 'ROS_STATIC_PEERS',
                   'FASTDDS_DEFAULT_PROFILES_FILE')
LOOPBACK = '127.0.0.1'


class LocalDdsError(RuntimeError):
    """The node was asked for the local DDS configuration and did not get it."""


def local_environment(profile: str = PROFILE) -> dict:
    """Return the environment variables of the local configuration."""
    return {MODE_ENV: LOCAL, RANGE_ENV: 'SYSTEM_DEFAULT', PROFILE_ENV: profile}


def requested(environ: Optional[Mapping[str, str]] = None) -> bool:
    """Return True when the environment asks for the local configuration (``MOVER6_DDS``)."""
    environ = os.environ if environ is None else environ
    mode = environ.get(MODE_ENV, '')
    if mode not in ('', LOCAL, LOCALHOST):
        raise LocalDdsError(f"{MODE_ENV}='{mode}': the values are '{LOCAL}' (the package's "
                            f"loopback-only profile, the launchers' default) and '{LOCALHOST}' "
                            "(ROS's LOCALHOST discovery)")
    return mode == LOCAL


def check_environment(environ: Optional[Mapping[str, str]] = None) -> None:
    """
    Raise ``LocalDdsError`` when the local configuration was asked for and is not selected.

    The message gives every reason; nothing happens when it was not asked for.
    """
    environ = os.environ if environ is None else environ
    if not requested(environ):
        return
    problems = []
    if environ.get(RANGE_ENV) != 'SYSTEM_DEFAULT':
        problems.append(f"{RANGE_ENV} is '{environ.get(RANGE_ENV, '')}', not SYSTEM_DEFAULT "
                        '(LOCALHOST adds shared memory, the stall of eProsima/Fast-DDS#6535)')
    profile = environ.get(PROFILE_ENV, '')
    if not profile:
        problems.append(f'{PROFILE_ENV} is not set (Fast DDS would use its defaults: multicast '
                        'on every interface)')
    elif not os.path.isfile(profile):
        problems.append(f'{PROFILE_ENV}={profile} is no file')
    elif not os.path.isfile(PROFILE):
        problems.append(f'the package has no profile {PROFILE} (install incomplete)')
    elif not filecmp.cmp(profile, PROFILE, shallow=False):
        problems.append(f'{PROFILE_ENV}={profile} is not the shipped profile {PROFILE}')
    for name in CONFLICTING_ENV:
        if environ.get(name):
            problems.append(f'{name} is set ({environ[name]}): it overrides the profile')
    if environ.get('ROS_LOCALHOST_ONLY', '0') not in ('', '0'):
        problems.append('ROS_LOCALHOST_ONLY is set: it selects LOCALHOST (shared memory)')
    if environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp') != 'rmw_fastrtps_cpp':
        problems.append(f"RMW_IMPLEMENTATION is '{environ['RMW_IMPLEMENTATION']}': the profile "
                        'is for rmw_fastrtps_cpp')
    if problems:
        raise LocalDdsError(_refusal(problems))


def _hex_ipv4(text):
    return socket.inet_ntoa(struct.pack('<I', int(text, 16)))


def socket_inodes(pid: Union[int, str]) -> set:
    """Return the inodes of the sockets process ``pid`` has open."""
    inodes = set()
    fd_dir = f'/proc/{pid}/fd'
    for fd in os.listdir(fd_dir):
        try:
            target = os.readlink(os.path.join(fd_dir, fd))
        except OSError:              # closed meanwhile
            continue
        if target.startswith('socket:['):
            inodes.add(target[len('socket:['):-1])
    return inodes


def ip_sockets(pid: Union[int, str]) -> list:
    """
    Return ``(protocol, local address, local port, inode)`` of every IP socket of ``pid``.

    From ``/proc/<pid>/net/{udp,udp6,tcp,tcp6}`` (the process's network namespace), matched by
    inode with the sockets in ``/proc/<pid>/fd``; IPv6 addresses as their hex text.
    """
    inodes = socket_inodes(pid)
    found = []
    for proto in ('udp', 'udp6', 'tcp', 'tcp6'):
        try:
            with open(f'/proc/{pid}/net/{proto}') as f:
                lines = f.readlines()[1:]
        except OSError:
            continue
        for line in lines:
            cols = line.split()
            if cols[9] in inodes:
                address, port = cols[1].split(':')
                if len(address) == 8:
                    address = _hex_ipv4(address)
                found.append((proto, address, int(port, 16), cols[9]))
    return found


def multicast_groups() -> list:
    """
    Return ``(interface, group)`` of the IPv4 multicast groups joined in this network namespace.

    From ``/proc/net/igmp``; 224.0.0.1 (all systems) is left out: the kernel joins it on every
    interface itself.
    """
    groups, interface = [], None
    with open('/proc/net/igmp') as f:
        for line in f.readlines()[1:]:
            cols = line.split()
            if not line[0].isspace():
                interface = cols[1]
            elif cols:
                group = _hex_ipv4(cols[0])
                if group != '224.0.0.1':
                    groups.append((interface, group))
    return groups


def not_loopback(sockets: list) -> list:
    """Return the sockets of ``ip_sockets`` not bound to 127.0.0.1."""
    return [s for s in sockets if s[1] != LOOPBACK]


def make_checked_node(make_node: Callable[[], Node]) -> Node:
    """
    Return ``make_node()``; asked for the local configuration, check the participant first.

    The participant of the process's context starts with its first node: a hidden probe node
    starts it, the sockets it opened (those that were not open before) must all be bound to
    127.0.0.1, else ``LocalDdsError``; only then is the node made (so it sends nothing in a
    wrong configuration), and the probe goes (the participant stays with the node).
    """
    if not requested():
        return make_node()
    import rclpy
    before = {s[3] for s in ip_sockets(os.getpid())}
    probe = rclpy.create_node(f'_mover6_dds_check_{os.getpid()}')
    try:
        opened = [s for s in ip_sockets(os.getpid()) if s[3] not in before]
        if not opened:
            raise LocalDdsError(_refusal(['its DDS participant opened no UDP socket']))
        wrong = not_loopback(opened)
        if wrong:
            raise LocalDdsError(_refusal(
                [f'its DDS participant has sockets not bound to {LOOPBACK}: '
                 f'{[s[:3] for s in wrong]} (Fast DDS did not apply the profile: it would '
                 'discover by multicast on every interface)']))
        return make_node()
    finally:
        probe.destroy_node()


def _refusal(problems):
    return (f'{MODE_ENV}={LOCAL} asks for the local DDS configuration (DDS on 127.0.0.1 only, '
            'no shared memory), but ' + '; '.join(problems) + '. Not starting. Set '
            f"{MODE_ENV}={LOCALHOST} for ROS's LOCALHOST discovery instead.")


def default_environment(environ: Mapping[str, str]) -> dict:
    """
    Return the DDS variables the launchers set in ``environ``: none when the user chose DDS.

    The local configuration on every machine (nothing sent leaves loopback, and no shared
    memory: no 1/3 s stall of every publish when a process joins the graph), unless the user set
    DDS variables of their own (a robot network: left as they are) or ``MOVER6_DDS=localhost``
    (ROS's ``LOCALHOST`` discovery; docs/dds.md).
    """
    mode = environ.get(MODE_ENV, '')
    requested(environ)                      # an unknown mode is refused
    chosen = [name for name in USER_DDS_ENV if environ.get(name) and name != MODE_ENV]
    if chosen:
        return {}
    if mode == LOCALHOST:
        return {RANGE_ENV: 'LOCALHOST'}
    return local_environment()


def apply_default(environ: MutableMapping[str, str]) -> None:
    """Set ``default_environment``'s variables in ``environ`` where it has none of its own."""
    for name, value in default_environment(environ).items():
        environ.setdefault(name, value)


def main(argv: Optional[list[str]] = None) -> int:
    """``env``: print the shell exports of ``default_environment`` (none: the user chose)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv != ['env']:
        print('usage: python -m mover6_control.nodes.runtime.local_dds env', file=sys.stderr)
        return 2
    try:
        exports = default_environment(os.environ)
    except LocalDdsError as err:
        print(err, file=sys.stderr)
        return 1
    for name, value in exports.items():
        print(f"export {name}='{value}'")
    return 0


if __name__ == '__main__':
    sys.exit(main())
