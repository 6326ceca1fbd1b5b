"""
Conversion between ROS messages and the core's plain numpy values: the one place that does it.

One message family has a module of its own: /joint_demands (the waypoints and the label that
carries a goal id and a profile) in ``nodes/messages/demand_messages.py``.

Every ``*_from_msg`` function validates and raises ``InvalidInputError`` with a reason a person can
read and a code (``errors.INPUT_CODES``); the nodes log that reason and drop the message. A pose
goal becomes a ``values.ToolPose`` and a JointJog a ``values.JogRequest`` here, once: the layers
below take them without checking again. Every ``make_*`` function builds a message.
"""

import math
from typing import Optional, Sequence

from builtin_interfaces.msg import Time
from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, TwistStamped
from mover6_control.errors import InvalidInputError, NonFiniteError
from mover6_control.kinematics.rotations import matrix_to_quaternion
from mover6_control.nodes.messages import cdr
from mover6_control.values import JogRequest, ToolPose
import numpy as np
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

STATUS_LEVELS = {
    'OK': DiagnosticStatus.OK,
    'WARN': DiagnosticStatus.WARN,
    'ERROR': DiagnosticStatus.ERROR,
    'STALE': DiagnosticStatus.STALE,
}


def stamp_to_seconds(stamp: Time) -> float:
    """Return a ``builtin_interfaces/Time`` as float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def seconds_to_stamp(seconds: float) -> Time:
    """Return a ``builtin_interfaces/Time`` for ``seconds`` [s] >= 0 (to the nanosecond)."""
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise InvalidInputError(f'a stamp needs finite seconds >= 0, got {seconds}')
    total = int(round(seconds * 1e9))
    stamp = Clock().clock
    stamp.sec, stamp.nanosec = divmod(total, 1_000_000_000)
    return stamp


def make_clock(seconds: float) -> Clock:
    """Build a rosgraph_msgs/Clock for sim time ``seconds`` [s]."""
    msg = Clock()
    msg.clock = seconds_to_stamp(seconds)
    return msg


# --- /joint_states -------------------------------------------------------------------------

def joint_state_from_msg(msg: JointState,
                         joint_names: Sequence[str]) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """
    Return ``(q, qd)`` (6,) [rad], [rad/s] from a JointState, mapped by name.

    ``qd`` is None when the message carries no velocities. Raises when a joint is missing, the
    arrays disagree in length, or a value is not finite.
    """
    names = list(msg.name)
    if len(msg.position) != len(names):
        raise InvalidInputError(
            f'joint_states has {len(names)} names but {len(msg.position)} positions', 'length')
    has_velocity = len(msg.velocity) > 0
    if has_velocity and len(msg.velocity) != len(names):
        raise InvalidInputError(
            f'joint_states has {len(names)} names but {len(msg.velocity)} velocities', 'length')
    index = {name: i for i, name in enumerate(names)}
    missing = [name for name in joint_names if name not in index]
    if missing:
        raise InvalidInputError(f'joint_states lacks joints {missing} (has {names})')
    q = np.array([msg.position[index[n]] for n in joint_names], dtype=float)
    qd = (np.array([msg.velocity[index[n]] for n in joint_names], dtype=float)
          if has_velocity else None)
    if not np.all(np.isfinite(q)) or (qd is not None and not np.all(np.isfinite(qd))):
        raise NonFiniteError('joint_states has non-finite values')
    return q, qd


def joint_state_fields_from_raw(raw: bytes, reader: 'cdr.JointStateReader') -> tuple:
    """Return ``(names, positions, velocities)`` of a serialized JointState, not yet checked."""
    try:                        # what the cdr reader does not read, rclpy does (or says why not)
        return reader.read_state(raw)[2:]
    except ValueError:
        msg = _deserialize(raw, JointState)
        return msg.name, msg.position, msg.velocity


def make_joint_state(joint_names: Sequence[str], q: Sequence[float],
                     qd: Optional[Sequence[float]] = None,
                     effort: Optional[Sequence[float]] = None,
                     stamp: Optional[Time] = None) -> JointState:
    """Build a JointState from arrays (6,) [rad], [rad/s], [N m]."""
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.name = list(joint_names)
    msg.position = [float(x) for x in q]
    if qd is not None:
        msg.velocity = [float(x) for x in qd]
    if effort is not None:
        msg.effort = [float(x) for x in effort]
    return msg


# --- poses ---------------------------------------------------------------------------------

def pose_from_msg(pose: Pose, name: str = 'pose') -> ToolPose:
    """Return the ``ToolPose`` of a geometry_msgs/Pose; raises on a bad quaternion or position."""
    p, o = pose.position, pose.orientation
    return ToolPose.from_position_quaternion([p.x, p.y, p.z], [o.x, o.y, o.z, o.w], name)


def matrix_to_pose(T: np.ndarray) -> Pose:
    """Build a geometry_msgs/Pose from ``T`` (4, 4)."""
    T = np.asarray(T, dtype=float)
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T[:3, 3])
    q = matrix_to_quaternion(T[:3, :3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        float(v) for v in q)
    return pose


GOAL_PROFILE_MARK = ' profile '


def goal_profile_from_header(header: Header) -> str:
    """
    Return the profile a goal asks for: its frame id ``base_link profile <name>``, else ''.

    The one text field of a PoseStamped or PoseArray carries the option, in the words of the
    demand label (``make_demands``), so ``ros2 topic pub`` can type it.
    """
    _, mark, profile = header.frame_id.partition(GOAL_PROFILE_MARK)
    if mark and len(profile.split()) != 1:
        raise InvalidInputError(f'goal frame "{header.frame_id}": expected '
                                '"<frame> profile <name>"')
    return profile.strip()


def check_frame(header: Header, expected_frame: str) -> None:
    """Raise when a header's frame is not ``expected_frame`` (an empty frame is accepted)."""
    frame = header.frame_id.partition(GOAL_PROFILE_MARK)[0].lstrip('/')
    if frame and frame != expected_frame:
        raise InvalidInputError(
            f'goal frame is "{header.frame_id}", expected "{expected_frame}" '
            '(no TF lookup is done: send goals in the base frame)', 'wrong_frame')


def pose_goal_from_msg(msg: PoseStamped, expected_frame: str = 'base_link') -> ToolPose:
    """Return the goal ``T_base_tool`` of a PoseStamped after checking its frame."""
    check_frame(msg.header, expected_frame)
    return pose_from_msg(msg.pose, 'goal pose')


def path_goal_from_msg(msg: PoseArray,
                       expected_frame: str = 'base_link') -> tuple[ToolPose, ...]:
    """Return the poses of a PoseArray (via poses, then the goal) after checking its frame."""
    check_frame(msg.header, expected_frame)
    if not msg.poses:
        raise InvalidInputError('path goal has no poses', 'empty')
    return tuple(pose_from_msg(p, f'path pose {i}') for i, p in enumerate(msg.poses))


# --- /JointJog -----------------------------------------------------------------------------

def make_joint_jog(joint_names: Sequence[str], velocities: Sequence[float],
                   stamp: Optional[Time] = None) -> JointJog:
    """Build a JointJog carrying ``velocities`` (6,) for all joints, ``displacements`` empty."""
    msg = JointJog()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.joint_names = list(joint_names)
    msg.velocities = [float(v) for v in velocities]
    return msg


def joint_jog_from_msg(msg: JointJog) -> JogRequest:
    """Return the ``JogRequest`` of a JointJog (velocities only: displacements are refused)."""
    return JogRequest.from_fields(msg.joint_names, msg.velocities, msg.displacements)


def joint_jog_from_raw(raw: bytes, reader: 'cdr.JointJogReader') -> JogRequest:
    """
    Return the ``JogRequest`` of a serialized JointJog's names and velocities.

    ``reader`` (a ``cdr.JointJogReader``) reads the fields; a sample it does not read is
    deserialised by rclpy (raises ``InvalidInputError`` when even that fails). The displacements
    are not read (the simulator's input takes velocities).
    """
    try:
        names, _, velocities = reader.read_jog(raw)
    except ValueError:
        msg = _deserialize(raw, JointJog)
        names, velocities = msg.joint_names, msg.velocities
    return JogRequest(names, velocities)


def _deserialize(raw, msg_type):
    try:
        return deserialize_message(raw, msg_type)
    except Exception as err:  # noqa: B902 - whatever rclpy raises for a malformed sample
        raise InvalidInputError(f'{msg_type.__name__} sample not readable: {err}') from err


# --- jogging: ~/delta_twist_cmds, ~/delta_joint_cmds -----------------------------------------

def twist_command_from_msg(msg: TwistStamped, now: float) -> tuple[float, list, list, str]:
    """
    Return ``(stamp, linear, angular, frame)`` of a TwistStamped jog command.

    A zero stamp (``ros2 topic pub`` leaves it so) counts as received at ``now`` [s]; an empty
    ``frame_id`` is ``base_link``. Raises on non-finite values and a malformed stamp.
    """
    linear = [msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z]
    angular = [msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z]
    if not all(math.isfinite(v) for v in linear + angular):
        raise NonFiniteError(f'twist has non-finite values: {linear} {angular}')
    return _jog_stamp(msg.header.stamp, now), linear, angular, msg.header.frame_id or 'base_link'


def joint_jog_command_from_msg(msg: JointJog, now: float) -> tuple[float, list, list]:
    """
    Return ``(stamp, names, velocities)`` of a JointJog jog command (velocities only).

    A zero stamp counts as received at ``now`` [s]; displacements are refused (not supported),
    and so is a malformed stamp.
    """
    jog = joint_jog_from_msg(msg)
    return _jog_stamp(msg.header.stamp, now), list(jog.names), list(jog.velocities)


def _jog_stamp(stamp, now):
    """Return a jog command's stamp [s] (``now`` for a zero one); raise for ``nanosec`` >= 1e9."""
    if stamp.nanosec >= 1_000_000_000:
        raise InvalidInputError(f'malformed stamp: nanosec {stamp.nanosec} is not below 1e9')
    seconds = stamp_to_seconds(stamp)
    return now if seconds == 0.0 else seconds


# --- status --------------------------------------------------------------------------------

def make_status(name: str, level: str, message: str, values: Optional[dict] = None,
                hardware_id: str = 'mover6') -> DiagnosticStatus:
    """Build a DiagnosticStatus; ``level`` is 'OK', 'WARN', 'ERROR' or 'STALE'."""
    msg = DiagnosticStatus()
    msg.level = STATUS_LEVELS[level]
    msg.name = name
    msg.message = message
    msg.hardware_id = hardware_id
    msg.values = [KeyValue(key=str(k), value=str(v)) for k, v in (values or {}).items()]
    return msg


def status_values(msg: DiagnosticStatus) -> dict:
    """Return the key/value pairs of a DiagnosticStatus as a dict of strings."""
    return {kv.key: kv.value for kv in msg.values}


def status_level_name(msg: DiagnosticStatus) -> str:
    """Return the level of a DiagnosticStatus as 'OK', 'WARN', 'ERROR' or 'STALE'."""
    for name, level in STATUS_LEVELS.items():
        if msg.level == level:
            return name
    return str(msg.level)
