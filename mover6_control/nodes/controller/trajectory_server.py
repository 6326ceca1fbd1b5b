"""
The controller's ``control_msgs/action/FollowJointTrajectory`` server.

What MoveIt and every tool that executes joint trajectories talk to, at the name
joint_trajectory_controller uses (``/controller/follow_joint_trajectory``). A goal's joints come
in any order and are mapped by name (the set must be the arm's six: INVALID_JOINTS otherwise);
its points become one demand of the controller, through the same queue as /joint_demands
(labelled ``waypoints goal fjt-<uuid>`` so the controller's status names it), so a goal outside
the joint limits is refused with the core's reason (INVALID_GOAL).

Timing: when the points carry ``time_from_start`` (any non-zero), the arm reaches each point at
its time, counted from when the controller takes the goal (``trajectory.header.stamp`` is not
used), with the points' ``velocities`` and ``accelerations`` when given (all points or none):
piecewise cubic or quintic Hermite from the present reference, as joint_trajectory_controller
interpolates (``control.timed_plan``; a first point at time 0 is the start state). When that
timing breaks a limit (a joint's speed, ``a_max``, a joint limit between the points) or cannot
be followed (times not increasing, a non-zero last velocity, a first point at time 0 far from
the arm) the goal is not refused: the arm goes time-optimal through the same points with the
controller's velocity law, the reason is logged as a warning and ends the result's
``error_string`` (the status value ``timing`` says the same). Points whose ``time_from_start``
are all zero are untimed: the law's motion (``profile``; the continuous law is time-optimal).

While the motion runs, feedback at ``FEEDBACK_PERIOD`` carries desired (the reference: the
timed plan or the law's, positions, velocities and ``time_from_start`` into it), actual (the
latest /joint_states) and their difference. Results: SUCCESSFUL when the controller
reports the motion arrived and every joint is within its goal tolerance;
GOAL_TOLERANCE_VIOLATED when a joint is not (or settling timed out); PATH_TOLERANCE_VIOLATED when
a joint leaves its path tolerance (the arm then stops with the usual deceleration) or the
controller aborted the motion (tracking error, stale states). Tolerances come from the goal by
joint name (0: the default, -1: none); the defaults are the controller's ``path_tolerance`` and
``goal_tolerance`` parameters. A cancel stops the arm with the usual deceleration and the goal
ends canceled once the arm is at rest. A new goal, or a /joint_demands message, preempts the
running goal: it is aborted with INVALID_GOAL (as joint_trajectory_controller) and the reason.

How a goal is read (joints by name, points, timing, tolerances) and which code a motion that
ended gets: ``nodes/controller/trajectory_goal.py``; here the server that runs it. It is served
by a node, an executor and a thread of its own (``nodes/controller/action_thread.py``): a goal of
10,000 points is built as Python objects there, not in the thread that takes /joint_states.
"""

from dataclasses import dataclass
import threading
from typing import Callable, Optional, Sequence, Tuple

from control_msgs.action import FollowJointTrajectory
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.motion_plan import MotionPlan
from mover6_control.control.status import (FINAL_RESULTS, MotionResult, State, StatusKey,
                                           TIMING_AS_GIVEN)
from mover6_control.control.timed_plan import Timing
from mover6_control.nodes.controller.goal_ledger import GoalLedger
from mover6_control.nodes.controller.trajectory_goal import (ended_code, map_goal, map_timing,
                                                             Result, tolerances, violations)
from mover6_control.nodes.messages import demand_messages
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.validation import short_text
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock
from rclpy.duration import Duration
from rclpy.executors import Executor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.task import Future
from trajectory_msgs.msg import JointTrajectoryPoint

FEEDBACK_PERIOD = 0.1    # [s]
# Longest wait [s] for the demand thread to accept or refuse a goal's demand: this, plus
# ACCEPT_PER_POINT for each point (the continuous law plans 10,000 points for seconds).
ACCEPT_TIMEOUT = 10.0
ACCEPT_PER_POINT = 0.005
# A motion's result counts once the controller has left these states.
ENDED_AFTER = (State.EXECUTING, State.SETTLING, State.STOPPING)


@dataclass(frozen=True)
class ControllerParts:
    """
    What the action server uses of the controller, given by the controller node.

    ``core`` is read and told to stop only under ``lock``; ``put_demand`` queues a goal's
    conversion on the demand thread, whose answer ``goals`` (the ledger) carries; ``now()`` is
    the node clock's time [s] and ``clock`` that clock (the server's waits run on it);
    ``running()`` says whether the controller still runs, ``last_q()`` gives the latest valid
    joint positions (or None) and ``parameter(name)`` a parameter's value (the default
    tolerances); ``guard`` wraps the server's callbacks as every other of the controller.
    """

    joint_names: Tuple[str, ...]
    core: ControllerCore
    lock: threading.RLock
    goals: GoalLedger
    put_demand: Callable[[Callable], None]
    guard: CallbackGuard
    clock: Clock
    logger: RcutilsLogger
    now: Callable[[], float]
    running: Callable[[], bool]
    last_q: Callable[[], Optional[Sequence[float]]]
    parameter: Callable[[str], object]


class FollowJointTrajectoryServer:
    """The action server of the controller; see the module docstring."""

    def __init__(self, controller: ControllerParts, server_node: Node, executor: Executor,
                 name: str):
        """
        Serve the action ``name`` for ``controller`` on ``server_node``.

        ``executor`` spins ``server_node`` (``controller_actions``: not the controller's).
        """
        self.controller = controller
        self.server_node = server_node
        self.executor = executor
        self.group = ReentrantCallbackGroup()
        self.active = None       # the goal handle being executed
        # Through the controller's guard (callback_guard); rclpy's own catches what execute raises.
        self.server = ActionServer(
            server_node, FollowJointTrajectory, name, self.execute,
            callback_group=self.group, **controller.guard.action_callbacks(
                lambda goal: GoalResponse.ACCEPT, lambda handle: CancelResponse.ACCEPT))

    def destroy(self) -> None:
        """Destroy the action server."""
        self.server.destroy()

    async def sleep(self, seconds: float, future: Optional[Future] = None) -> None:
        """Wait ``seconds`` on the node's clock, or until ``future`` is done, not holding it."""
        future = Future() if future is None else future
        timer = self.controller.guard.timer(
            seconds, lambda: future.done() or future.set_result(None), on=self.server_node,
            source='action wait', callback_group=self.group, clock=self.controller.clock)
        try:
            await future
        finally:
            self.server_node.destroy_timer(timer)

    def finish(self, handle: ServerGoalHandle, code: int, text: str, how: str = 'abort') -> Result:
        """End ``handle`` (abort, succeed or canceled) with ``code`` and ``text``."""
        getattr(handle, {'abort': 'abort', 'succeed': 'succeed', 'cancel': 'canceled'}[how])()
        # Two call sites: rclpy refuses one call site logging at two severities.
        if code == Result.SUCCESSFUL:
            self.controller.logger.info(f'follow_joint_trajectory: {text}')
        else:
            self.controller.logger.warning(f'follow_joint_trajectory: {text}')
        return Result(error_code=code, error_string=text)

    async def execute(self, handle: ServerGoalHandle) -> Result:
        """Run one goal to its end; return its ``Result``."""
        node = self.controller
        names = node.joint_names
        goal = handle.request
        goal_id = 'fjt-' + bytes(handle.goal_id.uuid).hex()[:12]
        path_tol = tolerances(goal.path_tolerance, names,
                              node.parameter('path_tolerance'))
        goal_tol = tolerances(goal.goal_tolerance, names,
                              node.parameter('goal_tolerance'))
        self.active = handle
        mapped = {}              # what the demand thread made of the goal

        def convert():
            """Map the goal's points in the demand thread (a long goal takes a while)."""
            try:
                mapped['rows'] = map_goal(goal.trajectory, names)
                mapped['timing'] = map_timing(goal.trajectory, names)
            except ValueError as err:
                mapped['code'] = err.args[0]
                node.goals.refused(goal_id, short_text(err.args[1]))
                return None
            demand = demand_messages.make_demands(mapped['rows'], goal_id)
            return (demand, mapped['timing']) if mapped['timing'].timed else demand

        taken = node.goals.expect(goal_id, self.executor)   # done when taken or refused
        node.put_demand(convert)
        if node.running():
            await self.sleep(ACCEPT_TIMEOUT + ACCEPT_PER_POINT * len(goal.trajectory.points),
                             taken)
        # The demand thread commits under the ledger's lock: taken, refused, or never.
        outcome = node.goals.withdraw(goal_id)
        if outcome is None:
            return self.finish(handle, Result.INVALID_GOAL, 'the controller did not '
                                                            'take the demand in time')
        if isinstance(outcome, str):
            return self.finish(handle, mapped.get('code', Result.INVALID_GOAL),
                               f'refused: {outcome}')
        motion_id = outcome
        rows, timing = mapped['rows'], mapped['timing']
        note = self.timing_note(goal_id, motion_id, timing)
        stopping = None          # why the arm is being stopped: (code, text, how)
        while node.running():
            with node.lock:
                status = node.core.status()
                plan = node.core.plan
            values = status.values
            if int(values[StatusKey.MOTION_ID]) != motion_id:
                other = (node.goals.goal_of(int(values[StatusKey.MOTION_ID]))
                         or '/joint_demands')
                # As joint_trajectory_controller: INVALID_GOAL, aborted, with the reason.
                return self.finish(handle, Result.INVALID_GOAL,
                                   f'goal {goal_id} preempted by {other} '
                                   f'(motion {values[StatusKey.MOTION_ID]})')
            desired, actual = self.reference(plan, motion_id), node.last_q()
            if actual is not None and desired is not None:
                error = [d - a for d, a in zip(desired[0], actual)]
                handle.publish_feedback(self.feedback(desired, actual, error))
                bad = violations(error, path_tol, names)
                if bad and stopping is None and values[StatusKey.STATE] == State.EXECUTING:
                    stopping = (Result.PATH_TOLERANCE_VIOLATED, f'path tolerance: {bad}',
                                'abort')
                    with node.lock:
                        node.core.request_stop(node.now())
            if handle.is_cancel_requested and stopping is None:
                stopping = (Result.SUCCESSFUL, 'canceled: stopped with the usual deceleration',
                            'cancel')
                with node.lock:
                    node.core.request_stop(node.now())
            result = values.get(StatusKey.RESULT)
            if result in FINAL_RESULTS and values[StatusKey.STATE] not in ENDED_AFTER:
                if stopping is not None:
                    return self.finish(handle, *stopping)
                if result == MotionResult.ARRIVED:
                    q_goal = [float(v) for v in rows[-1]]
                    q = node.last_q()
                    bad = violations([g - a for g, a in zip(q_goal, q)], goal_tol, names)
                    if bad:
                        return self.finish(handle, Result.GOAL_TOLERANCE_VIOLATED,
                                           f'goal tolerance: {bad}')
                    return self.finish(handle, Result.SUCCESSFUL,
                                       f'goal {goal_id} reached (motion {motion_id}){note}',
                                       'succeed')
                reason = values.get(StatusKey.REASON, status.message)
                return self.finish(handle, ended_code(values),
                                   f'motion {motion_id} {result}: {reason}')
            await self.sleep(FEEDBACK_PERIOD)
        return self.finish(handle, Result.PATH_TOLERANCE_VIOLATED, 'the controller closed')

    def timing_note(self, goal_id: str, motion_id: int, timing: Timing) -> str:
        """
        Log how a timed goal's timing is followed; return '' or '; timing: <why not>'.

        The controller's status names it (``timing``) for the motion the goal became.
        """
        if not timing.timed:
            return ''
        with self.controller.lock:
            values = self.controller.core.status().values
        note = (values.get(StatusKey.TIMING, '') if int(values[StatusKey.MOTION_ID]) == motion_id
                else '')
        if note == TIMING_AS_GIVEN:
            self.controller.logger.info(f'follow_joint_trajectory: goal {goal_id}: '
                                        f'time_from_start followed ({timing.times[-1]:.3f} s)')
            return ''
        if note:
            self.controller.logger.warning(f'follow_joint_trajectory: goal {goal_id}: {note}')
            return f'; timing: {note}'
        return ''

    def reference(self, plan: Optional[MotionPlan], motion_id: int) -> Optional[tuple]:
        """
        Return ``(q, qd, t)`` of the reference now (the goal once it ended), None before it.

        ``t`` [s] is the time into the plan, the feedback's ``time_from_start``.
        """
        start = self.controller.goals.start_of(motion_id)
        if plan is None or start is None:
            return None
        t = min(max(self.controller.now() - start, 0.0), plan.duration)
        q_ref, qd_ref = plan.sample(t)
        return [float(v) for v in q_ref], [float(v) for v in qd_ref], t

    def feedback(self, desired: tuple, actual: Sequence[float],
                 error: Sequence[float]) -> FollowJointTrajectory.Feedback:
        """Build a feedback message (joint order: the controller's)."""
        msg = FollowJointTrajectory.Feedback()
        msg.header.stamp = self.controller.clock.now().to_msg()
        msg.joint_names = list(self.controller.joint_names)
        q_ref, qd_ref, t = desired
        msg.desired = JointTrajectoryPoint(positions=q_ref, velocities=qd_ref)
        msg.desired.time_from_start = Duration(seconds=t).to_msg()
        msg.actual = JointTrajectoryPoint(positions=[float(v) for v in actual])
        msg.error = JointTrajectoryPoint(positions=error)
        return msg
