"""
One sender of /joint_states: a second one (a rogue publisher, a replay) holds the controller.

Two publishers of the states the controller closes its loop on give it two arms' positions in
turn, stale or conflicting: it would command from whichever came last. Every ``CHECK_PERIOD``
the controller counts the publishers of its /joint_states in the graph; while there is more than
one, its core refuses the states (``ControllerCore.distrust_states``) for ``DISTRUST_HOLD``
after each check: it faults, so the arm holds (a zero command), and the status names the
publishers. Once one is left the states are taken again and the fault clears as any fault
(valid states: idle).
"""

import threading
from typing import Callable

from mover6_control.control.controller_core import ControllerCore
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from rclpy.node import Node

CHECK_PERIOD = 0.5        # [s] between two counts of the publishers
DISTRUST_HOLD = 1.0       # [s] the states are refused after each count of more than one


class StatesSources:
    """Hold the controller while /joint_states has more than one publisher (module docstring)."""

    def __init__(self, node: Node, topic: str, core: ControllerCore, lock: threading.RLock,
                 guard: CallbackGuard, now: Callable[[], float]):
        """Count the publishers of ``topic`` in ``node``'s graph, on a timer of ``guard``."""
        self.node = node
        self.core = core
        self.lock = lock
        self.now = now
        self.topic = node.resolve_topic_name(topic)
        self.held = False
        guard.timer(CHECK_PERIOD, self.check, source=f'publishers of {self.topic}')

    def check(self) -> None:
        """Count the publishers; with more than one, refuse the states for ``DISTRUST_HOLD``."""
        infos = self.node.get_publishers_info_by_topic(self.topic)
        if len(infos) <= 1:
            if self.held:
                self.node.get_logger().info(f'{self.topic}: one publisher again')
            self.held = False
            return
        names = ', '.join(sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in infos))
        reason = (f'{len(infos)} publishers of {self.topic} ({names}): conflicting states, '
                  'the arm holds until one is left')
        with self.lock:
            self.core.distrust_states(self.now(), reason, DISTRUST_HOLD)
        if not self.held:
            self.node.get_logger().error(reason)
        self.held = True
