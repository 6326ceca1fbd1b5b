"""
The planner's handshake with the controller: a demand sent, then its one typed end.

A demand that names a goal (``demand_messages.make_demands``) goes out on /joint_demands (a
Float32MultiArray, the mission's interface) and the controller answers it on
``controller/demand_acks`` (``messages/demand_acks``: received at once, then taken, refused or
not ready). Each demand ends once, with an ``HandshakeEnd``:

- ``TAKEN``: the controller started its motion;
- ``REFUSED``: the controller refused the demand itself (limits, collision ...);
- ``NOT_READY``: the controller refused it for its state (no valid joint states, fault ...);
- ``SUPERSEDED``: a demand sent after it reached the controller first, so this one never did
  (sent before the controller's reader was matched): it is not sent again, which would replace
  the newer motion with an older one;
- ``NO_CONTROLLER``: no controller answers on the graph (no publisher of the answers) for
  ``wait()`` seconds in a row while the demand waits (none started, or it went away).

No resend timer: a demand that went out before the controller's reader was matched (the graph
can show a reader before the writer has matched it, and a volatile writer drops what it sent
before) is sent again when the writer matches a new reader (the publisher's matched event), and
only while no answer says it was received. The controller answers a goal it had already with
the answer it gave (one motion per goal).
"""

from collections import OrderedDict
from dataclasses import dataclass
import enum
import threading
import time
from typing import Any, Callable, Optional

from actionlib_msgs.msg import GoalStatus
from mover6_control.nodes.messages.demand_acks import ack_from_msg, ACK_QOS, ACK_TOPIC, Answer
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from rclpy.event_handler import PublisherEventCallbacks, QoSPublisherMatchedInfo
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from std_msgs.msg import Float32MultiArray

# [s] how often the graph is asked whether a controller answers, while a demand waits.
GRAPH_CHECK_PERIOD = 0.1


class HandshakeEnd(enum.Enum):
    """How a demand's handshake ended (module docstring)."""

    TAKEN = 'taken'
    REFUSED = 'refused'
    NOT_READY = 'not_ready'
    SUPERSEDED = 'superseded'
    NO_CONTROLLER = 'no_controller'


END_OF = {Answer.TAKEN: HandshakeEnd.TAKEN, Answer.REFUSED: HandshakeEnd.REFUSED,
          Answer.NOT_READY: HandshakeEnd.NOT_READY}


@dataclass
class Pending:
    """A demand sent and not yet ended; ``context`` is the sender's."""

    goal_id: str
    msg: Float32MultiArray
    context: Any
    received: bool = False              # the controller said it has it
    alone_since: Optional[float] = None   # [s, monotonic] since when no controller answers


class DemandHandshake:
    """Send demands on /joint_demands and end each with one ``HandshakeEnd`` (module docstring)."""

    def __init__(self, node: Node, guard: CallbackGuard, logger: RcutilsLogger,
                 on_end: Callable[[Pending, HandshakeEnd, str], None], wait: Callable[[], float]):
        """
        Publish /joint_demands on ``node``, read the answers through ``guard``.

        ``on_end(pending, outcome, text)`` is called once per demand (``text``: the
        controller's reason, or why it ended here); ``wait()`` [s] is how long a demand waits
        with no controller on the graph before it ends ``NO_CONTROLLER``.
        """
        self.node = node
        self.logger = logger
        self.on_end = on_end
        self.wait = wait
        self.lock = threading.Lock()
        self.pending = OrderedDict()     # goal id -> Pending, in the order sent
        self.publisher = node.create_publisher(
            Float32MultiArray, 'joint_demands', 10,
            event_callbacks=PublisherEventCallbacks(
                matched=guard.wrap('/joint_demands matched', self.on_matched)))
        self.answers_topic = node.resolve_topic_name(ACK_TOPIC)
        guard.subscription(GoalStatus, ACK_TOPIC, self.on_answer, ACK_QOS)
        guard.timer(GRAPH_CHECK_PERIOD, self.check, source='demand handshake')

    def matched(self) -> tuple[int, int]:
        """
        Return (matched, known): /joint_demands readers matched, and readers in the graph.

        A reader the graph shows but the publisher has not matched yet would miss a message
        published now (volatile durability); under load discovery can take a few seconds.
        """
        known = len(self.node.get_subscriptions_info_by_topic(self.publisher.topic_name))
        return self.publisher.get_subscription_count(), known

    def controllers(self) -> int:
        """Return how many controllers the graph shows (publishers of the answers)."""
        return self.node.count_publishers(self.answers_topic)

    def send(self, goal_id: str, msg: Float32MultiArray, context: Any) -> None:
        """Publish the demand ``msg`` of ``goal_id``; it ends by ``on_end`` (once)."""
        with self.lock:              # waiting before it is sent: a match meanwhile resends it
            self.pending[goal_id] = Pending(goal_id, msg, context)
        self.publisher.publish(msg)

    def drop(self) -> list[Pending]:
        """Forget every waiting demand (~/stop): none ends by ``on_end``; return them."""
        with self.lock:
            dropped, self.pending = list(self.pending.values()), OrderedDict()
        return dropped

    def waiting(self) -> int:
        """Return how many demands wait for their end."""
        with self.lock:
            return len(self.pending)

    def on_matched(self, info: QoSPublisherMatchedInfo) -> None:
        """Send again what no controller received, when the writer matched a new reader."""
        if info.current_count_change <= 0:
            return
        with self.lock:
            again = [p for p in self.pending.values() if not p.received]
        for pending in again:
            self.logger.info(f'goal {pending.goal_id}: a new reader of /joint_demands matched '
                             'before the controller said it had the demand: sent again')
            self.publisher.publish(pending.msg)

    def on_answer(self, msg: GoalStatus) -> None:
        """Take the controller's answer: received, or the demand's end (module docstring)."""
        ack = ack_from_msg(msg)
        ended = []
        with self.lock:
            pending = self.pending.get(ack.goal_id)
            if pending is None:
                return                   # another planner's goal, or one ended already
            # Demands sent before this one that the controller never had: superseded.
            for goal_id, earlier in list(self.pending.items()):
                if goal_id == ack.goal_id:
                    break
                if not earlier.received:
                    del self.pending[goal_id]
                    ended.append((earlier, HandshakeEnd.SUPERSEDED,
                                  f'goal {ack.goal_id}, sent after it, reached the controller '
                                  'first; this one did not, and is not sent again'))
            pending.received = True
            if ack.final:
                del self.pending[ack.goal_id]
                ended.append((pending, END_OF[ack.answer], ack.text))
        for pending, outcome, text in ended:
            self.on_end(pending, outcome, text)

    def check(self) -> None:
        """End ``NO_CONTROLLER`` the demands that waited ``wait()`` with no controller."""
        with self.lock:
            if not self.pending:
                return
        alone = self.controllers() == 0
        now, wait, ended = time.monotonic(), self.wait(), []
        with self.lock:
            for goal_id, pending in list(self.pending.items()):
                if not alone:
                    pending.alone_since = None
                    continue
                if pending.alone_since is None:
                    pending.alone_since = now
                if now - pending.alone_since >= wait:
                    del self.pending[goal_id]
                    ended.append(pending)
        for pending in ended:
            self.on_end(pending, HandshakeEnd.NO_CONTROLLER,
                        f'no controller answers on {self.answers_topic} (none for {wait:g} s): '
                        'is the controller running?')
