"""
Waiting for the nodes, for the goal command: spin until a condition holds or time is up.

``wait_ready`` waits for joint states, the controller's status and (for goals through the
planner) the planner's, each ready, then for the controller to stay ready a moment; its answer
is None or what was missing, said so that a user knows which node to start.

``Readiness`` is a part of ``goal_cli.GoalClient`` (a node with ``q``, ``controller_status``,
``planner_status`` and ``pose_pub``); it is not used on its own.
"""

import time
from typing import Callable, Optional

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.control.status import PlannerState, State, StatusKey
from mover6_control.nodes.messages import conversions
import rclpy

# The controller is not ready in these states: a demand would be refused.
NOT_READY = (None, State.WAITING_FOR_STATES, State.FAULT)


class Readiness:
    """Spin until a condition holds; wait for the nodes to be ready (module docstring)."""

    def spin_until(self, predicate: Callable[[], bool], timeout: float,
                   tick: Optional[Callable[[], None]] = None) -> bool:
        """Spin until ``predicate()`` is true or ``timeout`` [s] passes; return the predicate."""
        deadline = time.monotonic() + timeout
        while rclpy.ok() and not predicate():
            if time.monotonic() > deadline:
                return False
            rclpy.spin_once(self, timeout_sec=0.05)
            if tick is not None:
                tick()
        return bool(predicate())

    @staticmethod
    def values(msg: Optional[DiagnosticStatus]) -> dict:
        """Return a status message's values as a dict (empty for None)."""
        return conversions.status_values(msg) if msg is not None else {}

    def wait_ready(self, timeout: float = 30.0, need_planner: bool = True,
                   steady: float = 1.0) -> Optional[str]:
        """
        Wait for joint states, the controller's status and (optionally) the planner's.

        The planner must say it is ready (status value ``state``: it has received joint
        states), as the controller must have left ``waiting_for_states``.

        The controller must then stay ready (idle or moving, not waiting for states and not in
        fault) for ``steady`` [s]: nodes that have just started can stall briefly, and a demand
        that reaches a controller in fault is rejected.
        """
        checks = [('/joint_states (is the sim bridge or robot driver running?)',
                   lambda: self.q is not None),
                  ('/controller/status (is the controller running?)',
                   lambda: self.controller_status is not None),
                  ('the controller to receive /joint_states',
                   lambda: self.values(self.controller_status).get(StatusKey.STATE)
                   not in (None, State.WAITING_FOR_STATES))]
        if need_planner:
            checks += [('/planner/status (is the planner running?)',
                        lambda: self.planner_status is not None),
                       ('the planner to receive /joint_states',
                        lambda: self.values(self.planner_status).get(StatusKey.STATE)
                        == PlannerState.READY),
                       ('a subscriber on /pose_goal',
                        lambda: self.pose_pub.get_subscription_count() > 0),
                       ('the planner and the controller on /joint_demands',
                        lambda: self.on_topic('joint_demands', 'planner', 'controller'))]
        for what, check in checks:
            if not self.spin_until(check, timeout):
                return f'no {what} within {timeout:.0f} s'
        deadline = time.monotonic() + timeout
        ready_since = [time.monotonic()]

        def steady_ready():
            if self.values(self.controller_status).get(StatusKey.STATE) in NOT_READY:
                ready_since[0] = time.monotonic()
            return time.monotonic() - ready_since[0] >= steady
        if not self.spin_until(steady_ready, max(deadline - time.monotonic(), steady)):
            state = self.values(self.controller_status).get(StatusKey.STATE)
            return f'the controller did not stay ready for {steady:.1f} s (state {state})'
        return None

    def on_topic(self, topic: str, publisher_node: str, subscriber_node: str) -> bool:
        """Return True when the graph shows ``publisher_node`` and ``subscriber_node`` on it."""
        name = self.resolve_topic_name(topic)
        pubs = {info.node_name for info in self.get_publishers_info_by_topic(name)}
        subs = {info.node_name for info in self.get_subscriptions_info_by_topic(name)}
        return publisher_node in pubs and subscriber_node in subs
