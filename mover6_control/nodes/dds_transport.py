"""
Keep a node's DDS writes out of Fast DDS's shared-memory port opening (issue 12, item 3).

Measured (``bench/bench_churn.py``, ``bench/offcpu.py``): whenever a ROS process joins the graph,
every Fast DDS participant that sends to it for the first time over shared memory opens the new
process's port, and the port's health check waits about 333 ms (a third of the default
``healthy_check_timeout_ms``, even for a healthy port: eProsima/Fast-DDS issue 6535) while the
participant's send lock is held. Every write of the process waits for it (the controller's
JointJog: the driver halts), and the receive threads wait for discovery's lock meanwhile (no
/joint_states: the controller faults). rclpy keeps the interpreter lock in ``publish``, so the
whole node stands still.

Shared memory cannot be switched off in the usual ways while ``ROS_AUTOMATIC_DISCOVERY_RANGE``
is ``LOCALHOST``: rmw_fastrtps (Jazzy) then sets the participant's transports itself (shared
memory and UDPv4), ignoring ``FASTDDS_BUILTIN_TRANSPORTS`` and XML transport settings. What it
keeps from the default XML profile is the participant's GUID prefix, and Fast DDS uses shared
memory only with participants whose prefix names the same host. ``use_udp_between_processes``
writes a profile that gives this process's participant a prefix of its own (random "host" and
instance bytes, the process id), so Fast DDS treats every other process as remote and sends to
it over UDP on the loopback interface (``LOCALHOST`` still keeps discovery on this machine). The
other processes send to this one over shared memory as before: opening this process's port
happens in their participants, not here.

It must run before ``rclpy.init``. It leaves Fast DDS as it is when the environment already
names a profile file, when another RMW is selected, or when ``MOVER6_DDS_SHARED_MEMORY`` is 1.
"""

import atexit
import os
import secrets
import tempfile

KEEP_ENV = 'MOVER6_DDS_SHARED_MEMORY'
PROFILE_ENVS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')
EPROSIMA_VENDOR = b'\x01\x0f'
PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<!-- mover6_control.nodes.dds_transport: this process talks UDP to the others (see there). -->
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <participant profile_name="mover6_no_shared_memory_writes" is_default_profile="true">
    <rtps>
      <prefix>{prefix}</prefix>
    </rtps>
  </participant>
</profiles>
"""


def guid_prefix(pid: int, host: bytes = None, instance: bytes = None) -> str:
    """
    Return a GUID prefix ``01.0f.hh.hh.pp.pp.pp.pp.ii.ii.ii.ii`` (vendor, host, pid, instance).

    ``host`` and ``instance`` (2 and 4 bytes) are random unless given: a random host differs from
    the machine's (Fast DDS derives that from the machine), so no participant shares memory with
    this one; the process id and instance bytes keep prefixes unique, as Fast DDS's own do.
    """
    host = secrets.token_bytes(2) if host is None else host
    instance = secrets.token_bytes(4) if instance is None else instance
    raw = EPROSIMA_VENDOR + host + (pid & 0xFFFFFFFF).to_bytes(4, 'little') + instance
    return '.'.join(f'{b:02x}' for b in raw)


def use_udp_between_processes(environ=os.environ) -> str:
    """
    Make this process's Fast DDS participant send to other processes over UDP (see module doc).

    Writes the profile to a temporary file (removed at exit) and names it in ``environ``.
    Return one line for the log: what was done, or why not.
    """
    if environ.get(KEEP_ENV, '') == '1':
        return f'{KEEP_ENV}=1: Fast DDS shared memory kept (a joining process can stall writes)'
    rmw = environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    if not rmw.startswith('rmw_fastrtps'):
        return f'{rmw}: DDS transports left as they are'
    for name in PROFILE_ENVS:
        if environ.get(name):
            return (f'{name} is set: its profile is used as it is (to keep writes out of shared'
                    ' memory, see mover6_control.nodes.dds_transport)')
    fd, path = tempfile.mkstemp(prefix='mover6_dds_', suffix='.xml')
    with os.fdopen(fd, 'w') as f:
        f.write(PROFILE.format(prefix=guid_prefix(os.getpid())))
    atexit.register(_remove, path)
    environ[PROFILE_ENVS[0]] = path
    return ('DDS: this node sends to other processes over UDP (loopback), not shared memory '
            f'(a joining process cannot stall its writes); {KEEP_ENV}=1 keeps shared memory')


def logged(node, note):
    """Log ``note`` (the choice made before the node existed) on ``node``; return ``node``."""
    node.get_logger().info(note)
    return node


def _remove(path):
    try:
        os.remove(path)
    except OSError:
        pass
