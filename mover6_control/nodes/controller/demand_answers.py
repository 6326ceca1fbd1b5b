"""
The controller's answers to the demands that name a goal (``messages/demand_acks.py``).

``received`` answers at once, from the callback that takes the demand; ``answer`` gives the
final answer (taken, refused, not ready) from the demand thread. A demand sent again for a goal
already answered gets the same final answer again (``repeat``), never a second motion. The
latest ``ANSWERS_KEPT`` final answers are kept for that.
"""

from collections import OrderedDict
import threading
from typing import Callable

from actionlib_msgs.msg import GoalStatus
from mover6_control.nodes.messages.demand_acks import (ACK_QOS, ACK_TOPIC, Answer, DemandAck,
                                                       make_ack)
from rclpy.node import Node

ANSWERS_KEPT = 64


class DemandAnswers:
    """Publish the answers to goal demands on ``controller/demand_acks`` (module docstring)."""

    def __init__(self, node: Node, now_ns: Callable[[], int]):
        """Answer on a publisher of ``node``, stamped with ``now_ns()`` (the node clock)."""
        self.publisher = node.create_publisher(GoalStatus, ACK_TOPIC, ACK_QOS)
        self.now_ns = now_ns
        self.lock = threading.Lock()
        self.finals = OrderedDict()      # goal id -> its final DemandAck

    def received(self, goal_id: str) -> None:
        """Say that the demand of ``goal_id`` came (not yet planned)."""
        self._publish(DemandAck(goal_id, Answer.RECEIVED))

    def answer(self, goal_id: str, answer: Answer, text: str) -> None:
        """Give the final ``answer`` to the demand of ``goal_id``, with ``text``."""
        ack = DemandAck(goal_id, answer, text)
        with self.lock:
            self.finals[goal_id] = ack
            self.finals.move_to_end(goal_id)
            while len(self.finals) > ANSWERS_KEPT:
                self.finals.popitem(last=False)
        self._publish(ack)

    def repeat(self, goal_id: str) -> bool:
        """Give the final answer of ``goal_id`` again; False when there is none kept."""
        with self.lock:
            ack = self.finals.get(goal_id)
        if ack is not None:
            self._publish(ack)
        return ack is not None

    def _publish(self, ack: DemandAck) -> None:
        self.publisher.publish(make_ack(ack, *divmod(self.now_ns(), 1_000_000_000)))
