"""
The planner's delivery of a plan: its demand sent once a controller can hear it, and its end.

A demand is published once a controller is on the graph and the known readers of /joint_demands are
matched (or after ``match_timeout``; none matched: refused ``no_controller``), through the
``DemandHandshake``, which ends it once: taken (logged), or refused by the controller
(``controller_refused``, with its reason), not ready (``controller_not_ready``, with its reason),
superseded (failed, ``superseded``) or unanswered (failed, ``not_acknowledged``: no controller on
the graph for ``match_timeout``). ~/stop drops the waiting demands (refused, ``stopped``).

The demand goes out before its duration is predicted (``control.planners.predicted_duration``,
the controller's own timing of the plan: at 1000 waypoints most of the planning time, and no
check: every refusal comes before the demand). The status then says 'planned' with that
duration; an end that comes meanwhile is held (``Delivery.held``) and said after 'planned', in
the order the status always had.
"""

import dataclasses
import threading
import time
from typing import Callable, Optional

from mover6_control.control.planners import predicted_duration
from mover6_control.control.status import PlannerResult
from mover6_control.errors import Mover6Error
from mover6_control.kinematics.arm import ArmModel
from mover6_control.nodes.messages import demand_messages
from mover6_control.nodes.planner.goal_book import Goal, GoalBook
from mover6_control.nodes.planner.handshake import DemandHandshake, HandshakeEnd, Pending
from mover6_control.nodes.planner.status_publisher import PlannerStatus
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.planning.planner_core import JointPlan
import numpy as np
from rclpy.node import Node

# [s] how often a delivery waiting for readers to match looks again (stop, shutdown).
POLL = 0.02
# The planner's words for each end of the handshake but TAKEN: (reason, result, prefix).
ENDS = {
    HandshakeEnd.REFUSED: ('controller_refused', PlannerResult.REFUSED,
                           'the controller refused the demand: '),
    HandshakeEnd.NOT_READY: ('controller_not_ready', PlannerResult.REFUSED,
                             'the controller is not ready: '),
    HandshakeEnd.SUPERSEDED: ('superseded', PlannerResult.FAILED, ''),
    HandshakeEnd.NO_CONTROLLER: ('not_acknowledged', PlannerResult.FAILED, ''),
}
STOPPED = ('stopped before any controller answered', 'stopped', PlannerResult.REFUSED)


@dataclasses.dataclass
class Delivery:
    """A goal whose demand was sent: ``announced`` once 'planned' was said."""

    goal: Goal
    motion: str
    announced: bool = False
    held: Optional[tuple] = None   # (text, reason, result) of an end said once announced


class DemandDelivery:
    """Send the plans' demands and say how each ended (module docstring)."""

    def __init__(self, node: Node, guard: CallbackGuard, arm: ArmModel, status: PlannerStatus,
                 goals: GoalBook, match_timeout: Callable[[], float],
                 running: Callable[[], bool]):
        """
        Deliver on ``node`` (its graph and publisher, callbacks through ``guard``).

        ``match_timeout()`` [s] bounds the wait for readers and for a controller; ``running()``
        is False once the node closes.
        """
        self.arm = arm
        self.status = status
        self.goals = goals
        self.logger = node.get_logger()
        self.match_timeout = match_timeout
        self.running = running
        self.lock = threading.Lock()     # Delivery.announced, held
        self.handshake = DemandHandshake(node, guard, self.logger, self.on_end, match_timeout)

    def deliver(self, goal: Goal, motion: str, plan: JointPlan, profile: str,
                q_start: np.ndarray) -> None:
        """
        Publish the plan once a controller is there and the readers matched; say planned.

        It waits (``match_timeout`` at most) for a controller on the graph and for every known
        reader of /joint_demands to be matched. The duration ``profile`` takes from ``q_start``
        is predicted after the demand is out (module docstring).
        """
        since = time.monotonic()
        while True:
            matched, known = self.handshake.matched()
            waited = time.monotonic() - since
            if (matched >= max(known, 1) and self.handshake.controllers() > 0
                    or waited >= self.match_timeout()):
                break
            if self.goals.stopped(goal) or not self.running():
                break
            time.sleep(POLL)
        if self.goals.stopped(goal) or not self.running():
            self.status.refuse(motion, 'stopped before its demand was sent', 'stopped', {},
                               goal)
            return
        if matched == 0:
            self.status.refuse(motion, 'nobody subscribes to /joint_demands: is the controller '
                               'running?', 'no_controller', {}, goal)
            return
        msg = demand_messages.make_demands(plan.q, goal.goal_id, goal.profile)
        delivery = Delivery(goal, motion)
        self.handshake.send(goal.goal_id, msg, delivery)
        # One timing model: the controller's law times the waypoints from the same start.
        try:
            plan = dataclasses.replace(plan, predicted_duration=predicted_duration(
                profile, q_start, plan.q, self.arm.velocity_limits))
        except (Mover6Error, ValueError) as err:
            # Not a check (the controller times the demand and says if it refuses it): the
            # status keeps the planner's rough estimate.
            self.logger.warning(
                f'goal {goal.goal_id}: the duration was not predicted ({err}); the '
                f'estimate says {plan.predicted_duration:.2f} s')
        values = {'result': PlannerResult.PLANNED, 'motion': motion, 'waypoints': plan.n_waypoints,
                  'path_length': f'{plan.path_length:.6f}',
                  'predicted_duration': f'{plan.predicted_duration:.3f}',
                  'position_error': f'{plan.final_position_error:.3e}',
                  'orientation_error': f'{plan.final_orientation_error:.3e}'}
        text = (f'planned {motion} move: {plan.n_waypoints} waypoints, '
                f'{plan.path_length * 1e3:.1f} mm, about {plan.predicted_duration:.2f} s')
        self.logger.info(f'goal {goal.goal_id}: {text}')
        # The status first: the controller's refusal of the demand, or a stop, comes after it.
        self.status.publish('OK', text, values, goal)
        with self.lock:
            delivery.announced = True
            held = delivery.held
        if held is not None:
            self.say_end(delivery, *held)

    def on_end(self, pending: Pending, outcome: HandshakeEnd, text: str) -> None:
        """Say how the handshake of a demand ended (held until 'planned' was said)."""
        delivery = pending.context
        if outcome == HandshakeEnd.TAKEN:
            self.logger.info(f'goal {pending.goal_id}: the controller took it ({text})')
            return
        reason, result, prefix = ENDS[outcome]
        self.end(delivery, prefix + text, reason, result)

    def stop(self) -> None:
        """Drop every demand still waiting for its end (~/stop): each is refused, stopped."""
        for pending in self.handshake.drop():
            self.end(pending.context, *STOPPED)

    def end(self, delivery: Delivery, text: str, reason: str, result: PlannerResult) -> None:
        """Say the end of ``delivery`` now, or hold it until 'planned' was said."""
        with self.lock:
            if not delivery.announced:
                delivery.held = (text, reason, result)
                return
        self.say_end(delivery, text, reason, result)

    def say_end(self, delivery: Delivery, text: str, reason: str,
                result: PlannerResult) -> None:
        """Publish the end of ``delivery`` on the status."""
        self.status.refuse(delivery.motion, text, reason, {}, delivery.goal, result)
