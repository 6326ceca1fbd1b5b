"""
The planner's planning thread: the queued goals planned one after another.

A goal waits up to ``state_wait_timeout`` for fresh /joint_states (the planner says
``waiting_for_states`` meanwhile), is planned with the settings of the parameters in force
(``planning.planner_core``, ``planning.via_joint``) and its demand delivered (``delivery``); a
goal that ~/stop dropped is refused wherever it is. The node goes on reading states, answering
~/stop and the controller's answers while a goal is planned.
"""

from dataclasses import dataclass
import time
from typing import Callable, Optional

from mover6_control.control.profiles import LawConfig
from mover6_control.control.status import PlannerState
from mover6_control.errors import Mover6Error, UnreachableError
from mover6_control.nodes.planner.delivery import DemandDelivery
from mover6_control.nodes.planner.goal_book import Goal, GoalBook
from mover6_control.nodes.planner.joint_states import LatestJointStates
from mover6_control.nodes.planner.status_publisher import PlannerStatus
from mover6_control.nodes.runtime.job_thread import JobThread
from mover6_control.planning.planner_core import PlannerSettings
import numpy as np
from rclpy.impl.rcutils_logger import RcutilsLogger

WAITING, READY = PlannerState.WAITING_FOR_STATES, PlannerState.READY
# [s] how often a goal waiting for states looks again (stop, shutdown).
STATES_POLL = 0.1


@dataclass(frozen=True)
class PlanningJob:
    """A goal queued for planning: its shape ``motion``, ``plan_fn(q, settings)``, when it came."""

    goal: Goal
    motion: str
    plan_fn: Callable
    received: float          # [s, monotonic]


class PlanningThread:
    """Plan the queued goals in order (module docstring)."""

    def __init__(self, states: LatestJointStates, status: PlannerStatus,
                 delivery: DemandDelivery, goals: GoalBook,
                 settings: Callable[[], PlannerSettings], parameter: Callable[[str], object],
                 logger: RcutilsLogger):
        """
        Plan from ``states`` with ``settings()``; deliver through ``delivery``.

        ``parameter(name)`` reads the planner's ``state_timeout``, ``state_wait_timeout`` and
        ``profile``; ``status`` says what became of each goal.
        """
        self.states = states
        self.status = status
        self.delivery = delivery
        self.goals = goals
        self.settings = settings
        self.parameter = parameter
        self.logger = logger
        # The goals not yet planned, in order (``take_job``); closing it wakes a goal that
        # waits for joint states.
        self.jobs = JobThread('planner_planning', self.take_job, wake=states.came.set)

    @property
    def running(self) -> bool:
        """Return False once the thread is closed: a goal that waits for states stops waiting."""
        return self.jobs.running

    def start(self) -> None:
        """Start the planning thread."""
        self.jobs.start()

    def put(self, goal: Goal, motion: str, plan_fn: Callable, received: float) -> None:
        """Queue ``goal`` (shape ``motion``, plan function ``plan_fn(q, settings)``)."""
        self.jobs.put(PlanningJob(goal, motion, plan_fn, received))

    def close(self, timeout: float) -> None:
        """End the thread (a goal being planned finishes first); wait ``timeout`` [s]."""
        self.jobs.close(timeout)

    def take_job(self, job: PlanningJob) -> None:
        """Plan one queued goal; never raises (no goal ends without a status)."""
        try:
            self.plan_goal(job.goal, job.motion, job.plan_fn, job.received)
        except Exception as err:  # noqa: B902 - no goal ends without a status
            self.status.refuse(job.motion, f'{type(err).__name__}: {err}', 'internal_error', {},
                               job.goal)

    def plan_goal(self, goal: Goal, motion: str, plan_fn: Callable, received: float) -> None:
        """Plan one goal, then send its demand and say planned, or say why not."""
        if self.goals.stopped(goal):
            self.status.refuse(motion, 'stopped before it was planned', 'stopped', {}, goal)
            return
        try:
            q_now = self.wait_for_states(goal, motion, received)
            if q_now is None:
                return
            plan = plan_fn(q_now, self.settings())
            # The profile's name is checked before anything is sent (an unknown one is refused
            # here, as it was by the prediction); the duration is predicted once the demand is
            # out (``deliver``): the prediction refuses nothing.
            law = LawConfig(profile=goal.profile or self.parameter('profile'))
        except UnreachableError as err:
            self.status.refuse(motion, str(err), err.reason, err.details, goal)
            return
        except (Mover6Error, ValueError) as err:
            self.status.refuse(motion, str(err), 'invalid_goal', {}, goal)
            return
        self.delivery.deliver(goal, motion, plan, law.profile, q_now)

    def wait_for_states(self, goal: Goal, motion: str, received: float) -> Optional[np.ndarray]:
        """
        Return the current joint positions, waiting up to ``state_wait_timeout`` for them.

        Returns None when the goal ended meanwhile (refused: no states in time, or stopped).
        """
        wait = self.parameter('state_wait_timeout')
        said = False
        while True:
            self.states.came.clear()
            try:
                return self.states.current_q(self.parameter('state_timeout'))
            except Mover6Error as err:
                problem = err
            self.status.set_state(WAITING)
            left = received + wait - time.monotonic()
            if self.goals.stopped(goal) or not self.running:
                self.status.refuse(motion, 'stopped while waiting for /joint_states', 'stopped',
                                   {}, goal)
                return None
            if left <= 0.0:
                self.status.refuse(motion, f'no valid /joint_states within {wait:g} s: {problem}',
                                   'no_joint_states', {}, goal)
                return None
            if not said:
                said = True
                self.logger.info(f'goal {goal.goal_id}: waiting up to {left:.1f} s '
                                 f'for /joint_states ({problem})')
                self.status.publish('WARN', f'goal waits for /joint_states: {problem}',
                                    {'result': WAITING, 'motion': motion,
                                     'wait_timeout': f'{wait:g}'}, goal)
            self.states.came.wait(min(left, STATES_POLL))
