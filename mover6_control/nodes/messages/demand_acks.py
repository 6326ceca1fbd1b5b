"""
The controller's answers to the demands that name a goal: ``actionlib_msgs/GoalStatus``, typed.

A demand on /joint_demands stays a Float32MultiArray (what a user types into ``ros2 topic pub``);
one whose label names a goal (``waypoints goal <id>``, ``demand_messages``) is answered on
``controller/demand_acks`` with a ``GoalStatus``: ``goal_id.id`` the goal, ``goal_id.stamp``
the controller's time of the answer, ``status`` the answer's code and ``text`` the reason. The
codes are actionlib's, in their meaning:

- ``RECEIVED`` (PENDING): the controller has the demand, not yet planned (sent from the
  callback that takes it, before the demand thread plans anything);
- ``TAKEN`` (ACTIVE): its motion started (``text``: ``motion <id>``);
- ``REFUSED`` (REJECTED): refused for itself (limits, a collision, a bad label ...);
- ``NOT_READY`` (RECALLED: never started): refused for the controller's state (waiting for
  joint states, fault ...), not for the demand.

The topic is reliable and transient local (``ACK_QOS``): a planner that matches the controller
late still reads the latest answers. ``ack_from_msg`` checks a message once into a frozen
``DemandAck``; nothing reads the text to decide.
"""

from dataclasses import dataclass
import enum

from actionlib_msgs.msg import GoalStatus
from mover6_control.errors import InvalidInputError
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

ACK_TOPIC = 'controller/demand_acks'
# Answers kept for a late reader: more than goals a planner waits on at once.
ACK_DEPTH = 32
ACK_QOS = QoSProfile(depth=ACK_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Answer(enum.IntEnum):
    """The controller's answer to a demand, as a ``GoalStatus.status`` code."""

    RECEIVED = GoalStatus.PENDING
    TAKEN = GoalStatus.ACTIVE
    REFUSED = GoalStatus.REJECTED
    NOT_READY = GoalStatus.RECALLED


FINAL = (Answer.TAKEN, Answer.REFUSED, Answer.NOT_READY)


@dataclass(frozen=True)
class DemandAck:
    """One answer: the goal it is about, the answer and the reason (or ``motion <id>``)."""

    goal_id: str
    answer: Answer
    text: str = ''

    @property
    def final(self) -> bool:
        """Return whether this answer ends the demand's handshake (all but RECEIVED)."""
        return self.answer in FINAL


def make_ack(ack: DemandAck, sec: int, nanosec: int) -> GoalStatus:
    """Build the ``GoalStatus`` of ``ack``, stamped ``sec``.``nanosec`` (controller's clock)."""
    msg = GoalStatus(status=int(ack.answer), text=ack.text)
    msg.goal_id.id = ack.goal_id
    msg.goal_id.stamp.sec, msg.goal_id.stamp.nanosec = sec, nanosec
    return msg


def ack_from_msg(msg: GoalStatus) -> DemandAck:
    """Return the ``DemandAck`` of a ``GoalStatus``; raise ``InvalidInputError`` when unusable."""
    if not msg.goal_id.id:
        raise InvalidInputError('a demand answer without a goal id')
    try:
        answer = Answer(msg.status)
    except ValueError:
        raise InvalidInputError(f'goal {msg.goal_id.id}: answer code {msg.status} is none of '
                                f'{[a.name for a in Answer]}') from None
    return DemandAck(msg.goal_id.id, answer, msg.text)
