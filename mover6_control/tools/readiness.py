"""
Waiting for the nodes, for the goal command: spin until a condition holds or time is up.

``Spinner`` spins one node until a condition holds. ``LatestStatus`` keeps what the goal command
hears: the latest joint positions, the planner's and the controller's status, the latest
demands. ``Readiness`` waits for joint states, the controller's status and (for goals through
the planner) the planner's, each ready, then for the controller to stay ready a moment; its
answer is None or what was missing, said so that a user knows which node to start. Each is a
class of its own, given what it uses in its constructor; ``goal_cli.GoalClient`` composes them.
"""

import time
from typing import Callable, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.control.status import PlannerState, State, StatusKey
from mover6_control.errors import Mover6Error
from mover6_control.nodes.messages import conversions, demand_messages
import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.publisher import Publisher
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

# The controller is not ready in these states: a demand would be refused.
NOT_READY = (None, State.WAITING_FOR_STATES, State.FAULT)


def status_values(msg: Optional[DiagnosticStatus]) -> dict:
    """Return a status message's values as a dict (empty for None)."""
    return conversions.status_values(msg) if msg is not None else {}


class Spinner:
    """Spin ``node`` until a condition holds or time is up."""

    def __init__(self, node: Node) -> None:
        self.node = node

    def spin_until(self, predicate: Callable[[], bool], timeout: float,
                   tick: Optional[Callable[[], None]] = None) -> bool:
        """Spin until ``predicate()`` is true or ``timeout`` [s] passes; return the predicate."""
        deadline = time.monotonic() + timeout
        while rclpy.ok() and not predicate():
            if time.monotonic() > deadline:
                return False
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if tick is not None:
                tick()
        return bool(predicate())


class LatestStatus:
    """
    The latest of what the goal command hears, and the controller's refusal of its goal.

    ``joint_names`` map /joint_states onto the arm; ``goal_id`` is the goal being followed
    (a refusal of another goal is not its refusal). Malformed messages are left out.
    """

    def __init__(self, joint_names: Sequence[str]) -> None:
        self.joint_names = list(joint_names)
        self.planner_status: Optional[DiagnosticStatus] = None
        self.controller_status: Optional[DiagnosticStatus] = None
        self.q: Optional[np.ndarray] = None
        self.last_demands: Optional[np.ndarray] = None
        self.rejection: Optional[str] = None
        self.goal_id: Optional[str] = None

    def on_planner(self, msg: DiagnosticStatus) -> None:
        """Keep the planner's latest status."""
        self.planner_status = msg

    def on_controller(self, msg: DiagnosticStatus) -> None:
        """Keep the controller's latest status, and note when it rejected the goal followed."""
        self.controller_status = msg
        values = status_values(msg)
        rejected = values.get(StatusKey.REJECTED)
        if rejected and self.goal_id is not None and values.get(StatusKey.REJECTED_GOAL_ID) in (
                self.goal_id, ''):
            self.rejection = rejected

    def on_joint_states(self, msg: JointState) -> None:
        """Keep the latest joint positions."""
        try:
            self.q, _ = conversions.joint_state_from_msg(msg, self.joint_names)
        except Mover6Error:
            pass

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Keep the latest joint demands (the planner's output)."""
        try:
            self.last_demands = demand_messages.demands_from_msg(msg, len(self.joint_names))
        except Mover6Error:
            pass

    def follow(self, goal_id: Optional[str]) -> None:
        """Start following the goal ``goal_id``: no demands and no refusal heard for it yet."""
        self.last_demands = None
        self.rejection = None
        self.goal_id = goal_id


class Readiness:
    """
    Wait for the nodes a goal needs to be ready (module docstring).

    ``spinner`` spins, ``latest`` is what was heard, ``pose_pub`` the /pose_goal publisher (its
    subscriber is the planner) and ``graph`` the node whose view of the ROS graph is asked.
    """

    def __init__(self, spinner: Spinner, latest: LatestStatus, pose_pub: Publisher,
                 graph: Node) -> None:
        self.spinner = spinner
        self.latest = latest
        self.pose_pub = pose_pub
        self.graph = graph

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
        latest, spin_until = self.latest, self.spinner.spin_until
        checks = [('/joint_states (is the sim bridge or robot driver running?)',
                   lambda: latest.q is not None),
                  ('/controller/status (is the controller running?)',
                   lambda: latest.controller_status is not None),
                  ('the controller to receive /joint_states',
                   lambda: status_values(latest.controller_status).get(StatusKey.STATE)
                   not in (None, State.WAITING_FOR_STATES))]
        if need_planner:
            checks += [('/planner/status (is the planner running?)',
                        lambda: latest.planner_status is not None),
                       ('the planner to receive /joint_states',
                        lambda: status_values(latest.planner_status).get(StatusKey.STATE)
                        == PlannerState.READY),
                       ('a subscriber on /pose_goal',
                        lambda: self.pose_pub.get_subscription_count() > 0),
                       ('the planner and the controller on /joint_demands',
                        lambda: self.on_topic('joint_demands', 'planner', 'controller'))]
        for what, check in checks:
            if not spin_until(check, timeout):
                return f'no {what} within {timeout:.0f} s'
        deadline = time.monotonic() + timeout
        ready_since = [time.monotonic()]

        def steady_ready():
            if status_values(latest.controller_status).get(StatusKey.STATE) in NOT_READY:
                ready_since[0] = time.monotonic()
            return time.monotonic() - ready_since[0] >= steady
        if not spin_until(steady_ready, max(deadline - time.monotonic(), steady)):
            state = status_values(latest.controller_status).get(StatusKey.STATE)
            return f'the controller did not stay ready for {steady:.1f} s (state {state})'
        return None

    def on_topic(self, topic: str, publisher_node: str, subscriber_node: str) -> bool:
        """Return True when the graph shows ``publisher_node`` and ``subscriber_node`` on it."""
        name = self.graph.resolve_topic_name(topic)
        pubs = {info.node_name for info in self.graph.get_publishers_info_by_topic(name)}
        subs = {info.node_name for info in self.graph.get_subscriptions_info_by_topic(name)}
        return publisher_node in pubs and subscriber_node in subs
