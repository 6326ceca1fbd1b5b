"""
Following one goal of the goal command to its end: planned or refused, then arrived or not.

``MotionFollower`` publishes a goal, follows the planner's status about it (by its stamp), then
the controller's (by the goal id the planner gave it), and returns its ``Outcome`` with the
figures of the pose reached. A part of ``goal_cli.GoalClient``, given what it uses in its
constructor: a ``readiness.Spinner``, the ``readiness.LatestStatus`` the client keeps, the arm.
"""

import time
from typing import Callable, Optional

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.control.status import (FINAL_RESULTS, MotionResult, PlannerResult, State,
                                           StatusKey)
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import pose_error
from mover6_control.tools.goal_convention import (EXIT_ARRIVED, EXIT_FAILED, EXIT_REFUSED,
                                                  Outcome)
from mover6_control.tools.readiness import LatestStatus, Spinner, status_values
import numpy as np

# [s] longest wait for the planner's answer about a goal (more when it says the goal waits for
# joint states: by as much as it says).
PLANNER_ANSWER_WAIT = 15.0
# [s] longest wait, after arrival, for the controller to finish settling (its settle_time is 1 s).
SETTLE_WAIT = 5.0


class MotionFollower:
    """
    Follow one goal, and only it, to its end: planned or refused, then arrived or not.

    ``spinner`` spins, ``latest`` is what the client hears (``readiness.LatestStatus``), ``arm``
    gives the tool pose of the joint positions heard.
    """

    def __init__(self, spinner: Spinner, latest: LatestStatus, arm: ArmModel) -> None:
        self.spinner = spinner
        self.latest = latest
        self.arm = arm

    def run(self, publish: Callable[[], None], T_goal: Optional[np.ndarray] = None,
            planned: bool = True, timeout: float = 60.0,
            progress: Optional[Callable[[str], None]] = None, stamp: Optional[Time] = None,
            goal_id: Optional[str] = None) -> Outcome:
        """
        Publish a goal with ``publish()``, then follow it, and only it, to its end.

        ``planned`` goals go through the planner: its status about the goal stamped ``stamp``
        (a ``builtin_interfaces/Time``) says planned or refused and gives the goal's id; others
        go straight to /joint_demands labelled ``goal_id``. The controller's status about that
        id says how the motion ended. ``T_goal`` (4, 4), when given, yields the tool position
        error. ``progress(text)`` is called about twice a second while the arm moves.
        """
        latest, spin_until, values = self.latest, self.spinner.spin_until, status_values
        latest.follow(goal_id)
        t0 = time.monotonic()
        publish()
        demands = None
        if planned:
            mine = f'{stamp.sec}.{stamp.nanosec:09d}'

            def about_mine(results=None):
                v = values(latest.planner_status)
                return v.get(StatusKey.GOAL_STAMP) == mine and (
                    results is None or v.get(StatusKey.RESULT) in results)
            # A goal that came before the planner's joint states waits for them (and says so,
            # with how long it may wait): then planned or refused.
            answered = (PlannerResult.PLANNED, PlannerResult.REFUSED, PlannerResult.FAILED)
            waiting = (PlannerResult.WAITING_FOR_STATES,)
            if not spin_until(lambda: about_mine(answered) or about_mine(waiting),
                              PLANNER_ANSWER_WAIT):
                return Outcome(EXIT_FAILED, 'the planner did not answer within '
                               f'{PLANNER_ANSWER_WAIT:.0f} s')
            if not about_mine(answered):
                wait = float(values(latest.planner_status).get('wait_timeout', 0.0))
                if not spin_until(lambda: about_mine(answered), wait + PLANNER_ANSWER_WAIT):
                    return Outcome(EXIT_FAILED, 'the planner did not plan the goal within '
                                   f'{wait + PLANNER_ANSWER_WAIT:.0f} s')
            status = latest.planner_status
            latest.goal_id = values(status).get(StatusKey.GOAL_ID)
            if status.level != DiagnosticStatus.OK:
                return Outcome(EXIT_REFUSED, status.message, **values(status))
            spin_until(lambda: latest.last_demands is not None, 5.0)
            demands = latest.last_demands

        def mine_now():
            return values(latest.controller_status).get(StatusKey.GOAL_ID) == latest.goal_id

        def planner_ended():
            # After 'planned' the planner reports the controller's refusal of the demand, or
            # that no controller acknowledged it.
            v = values(latest.planner_status)
            return (planned and v.get(StatusKey.GOAL_ID) == latest.goal_id
                    and v.get(StatusKey.RESULT) in (PlannerResult.REFUSED, PlannerResult.FAILED))

        def motion_done():
            v = values(latest.controller_status)
            return latest.rejection is not None or planner_ended() or (
                mine_now() and v.get(StatusKey.RESULT) in FINAL_RESULTS)

        last_print = [0.0]

        def tick():
            if progress is None or time.monotonic() - last_print[0] < 0.5:
                return
            v = values(latest.controller_status)
            if not mine_now():
                return   # the status still describes another motion
            last_print[0] = time.monotonic()
            text = (f'{v.get(StatusKey.STATE, "?")}: waypoint {v.get(StatusKey.WAYPOINT, "?")} '
                    f'of {v.get(StatusKey.WAYPOINTS, "?")}')
            if T_goal is not None and latest.q is not None:
                left = np.linalg.norm(fk(self.arm, latest.q)[:3, 3] - T_goal[:3, 3])
                text += f', {left * 1e3:.1f} mm to go'
            progress(text)

        if not spin_until(motion_done, timeout, tick):
            return Outcome(EXIT_FAILED, f'the motion did not finish within {timeout:.0f} s')
        if latest.rejection is not None:
            return Outcome(EXIT_REFUSED, f'the controller refused the demand: {latest.rejection}')
        if planner_ended():
            status = latest.planner_status
            refused = values(status).get(StatusKey.RESULT) == PlannerResult.REFUSED
            code = EXIT_REFUSED if refused else EXIT_FAILED
            return Outcome(code, status.message, **values(status))
        # 'arrived' comes once inside the goal tolerance; the controller then keeps settling
        # into its fine tolerance before it holds: report the pose it holds.
        spin_until(lambda: values(latest.controller_status).get(StatusKey.STATE)
                   != State.SETTLING, SETTLE_WAIT)
        v = values(latest.controller_status)
        # Let one fresh /joint_states arrive after the end so the figures are of the final pose.
        stamp = [latest.q]
        spin_until(lambda: latest.q is not stamp[0], 2.0)
        figures = {'duration': time.monotonic() - t0, 'result': v.get(StatusKey.RESULT)}
        if demands is None and latest.last_demands is not None:
            demands = latest.last_demands
        if demands is not None and latest.q is not None:
            figures['final_joint_error'] = float(np.abs(latest.q - demands[-1]).max())
        if latest.q is not None:
            figures['reached_pose'] = fk(self.arm, latest.q)
        if T_goal is not None and latest.q is not None:
            figures['final_position_error'], figures['final_orientation_error'] = pose_error(
                figures['reached_pose'], T_goal)
        if v.get(StatusKey.RESULT) != MotionResult.ARRIVED:
            return Outcome(EXIT_FAILED, latest.controller_status.message, **figures)
        return Outcome(EXIT_ARRIVED, 'arrived', **figures)
