"""
The planner node's planning thread: the queued goals planned one after another.

A goal waits up to ``state_wait_timeout`` for fresh /joint_states (the planner says
``waiting_for_states`` meanwhile), is planned with the settings of the parameters in force
(``planning.planner_core``, ``planning.via_joint``) and its demand delivered
(``planner_delivery``); a goal that ~/stop dropped is refused wherever it is. The node goes on
reading states, answering ~/stop and the controller's status while a goal is planned.

``PlanningThread`` is a part of ``planner_node.PlannerNode`` (its state is the node's, set in
``PlannerNode.__init__``); it is not used on its own.
"""

import queue
import time
from typing import Callable, Optional

from mover6_control.collision.checker import CollisionChecker
from mover6_control.control.profiles import LawConfig
from mover6_control.control.status import PlannerState
from mover6_control.errors import Mover6Error, UnreachableError
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.nodes.runtime.node_configs import planner_settings_from_parameters
from mover6_control.planning.planner_core import PlannerSettings
import numpy as np

WAITING, READY = PlannerState.WAITING_FOR_STATES, PlannerState.READY
# [s] how often a waiting planning thread looks again (states, stop, shutdown).
POLL = 0.02


class PlanningThread:
    """The planning thread of ``PlannerNode`` (module docstring)."""

    def frame_id(self) -> str:
        """Return the frame goals must be given in."""
        return self.get_parameter('frame_id').value

    def settings(self) -> PlannerSettings:
        """Return the planner settings from the current parameters."""
        return planner_settings_from_parameters(lambda n: self.get_parameter(n).value)

    def checker(self, settings: PlannerSettings) -> Optional[CollisionChecker]:
        """Return the collision checker of ``settings`` (kept while they do not change)."""
        if not settings.collision.enabled:
            return None
        if self._checker is None or self._checker.settings != settings.collision:
            self._checker = CollisionChecker(self.arm, settings.collision)
        return self._checker

    def current_q(self) -> np.ndarray:
        """Return the latest joint positions, or raise when there are none or they are old."""
        if self.states is None:
            raise Mover6Error('no /joint_states received yet: the current pose is unknown')
        raw, arrival = self.states
        age = (now_ns(self.get_clock()) - arrival) * 1e-9
        timeout = self.get_parameter('state_timeout').value
        if age > timeout:
            raise Mover6Error(f'/joint_states are {age:.2f} s old (limit {timeout:.2f} s): '
                              'the current pose is uncertain')
        return self.positions(raw).copy()

    def plan_loop(self) -> None:
        """Plan the queued goals in order; send demands again until acknowledged."""
        while self.running:
            try:
                job = self.jobs.get(timeout=self.resend_due())
            except queue.Empty:
                job = ()
            if job is None or not self.running:
                return
            if job:
                try:
                    self.plan_goal(*job)
                except Exception as err:  # noqa: B902 - no goal ends without a status
                    self.refuse(job[1], f'{type(err).__name__}: {err}', 'internal_error', {},
                                job[0])
            self.confirm_delivery()

    def stopped(self, goal: dict) -> bool:
        """Return True when ~/stop dropped ``goal``."""
        return goal['goal_seq'] <= self.stopped_seq

    def plan_goal(self, goal: dict, motion: str, plan_fn: Callable, received: float) -> None:
        """Plan one goal, then send its demand and say planned, or say why not."""
        if self.stopped(goal):
            self.refuse(motion, 'stopped before it was planned', 'stopped', {}, goal)
            return
        try:
            q_now = self.wait_for_states(goal, motion, received)
            if q_now is None:
                return
            plan = plan_fn(q_now, self.settings())
            # The profile's name is checked before anything is sent (an unknown one is refused
            # here, as it was by the prediction); the duration is predicted once the demand is
            # out (``deliver``): the prediction refuses nothing.
            law = LawConfig(profile=goal.get('profile') or self.get_parameter('profile').value)
        except UnreachableError as err:
            self.refuse(motion, str(err), err.reason, err.details, goal)
            return
        except (Mover6Error, ValueError) as err:
            self.refuse(motion, str(err), 'invalid_goal', {}, goal)
            return
        self.deliver(goal, motion, plan, law.profile, q_now)

    def wait_for_states(self, goal: dict, motion: str, received: float) -> Optional[np.ndarray]:
        """
        Return the current joint positions, waiting up to ``state_wait_timeout`` for them.

        Returns None when the goal ended meanwhile (refused: no states in time, or stopped).
        """
        wait = self.get_parameter('state_wait_timeout').value
        said = False
        while True:
            self.states_came.clear()
            try:
                return self.current_q()
            except Mover6Error as err:
                problem = err
            if self.state != WAITING:
                self.set_state(WAITING)
            left = received + wait - time.monotonic()
            if self.stopped(goal) or not self.running:
                self.refuse(motion, 'stopped while waiting for /joint_states', 'stopped', {},
                            goal)
                return None
            if left <= 0.0:
                self.refuse(motion, f'no valid /joint_states within {wait:g} s: {problem}',
                            'no_joint_states', {}, goal)
                return None
            if not said:
                said = True
                self.get_logger().info(f'goal {goal["goal_id"]}: waiting up to {left:.1f} s '
                                       f'for /joint_states ({problem})')
                self.publish_status('WARN', f'goal waits for /joint_states: {problem}',
                                    {'result': WAITING, 'motion': motion,
                                     'wait_timeout': f'{wait:g}'}, goal)
            self.states_came.wait(min(left, POLL * 5))
