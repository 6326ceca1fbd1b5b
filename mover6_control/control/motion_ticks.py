"""
The ticks of a motion in the controller, one per state: executing, settling, stopping.

Executing follows the plan's reference (its time running at the speed scaling factor,
``speed_scaling``) with the closed loop (a tracking error above
``path_tolerance`` stops the motion); settling holds the goal until every joint is inside the
goal tolerance (result 'arrived'), then closes the last of the error down to the settle
tolerance (behind a driver with a cycle, counting what is in flight: ``driver_compensation``);
stopping follows the stop plan to rest.

``MotionTicks`` is made with what it reads and changes: the robot (the plan, its reference, the
measured states), the ``CoreState`` it shares with the other parts of
``controller_core.ControllerCore`` (the state machine, the motion's figures, the settings) and
the ``DriverCompensation`` of a driver with a cycle. A test builds it alone from those.
"""

from __future__ import annotations

from typing import Optional

from mover6_control.control import state_machine as sm
from mover6_control.control.core_state import CoreState
from mover6_control.control.driver_compensation import DriverCompensation
from mover6_control.control.motion_plan import plan_stop
from mover6_control.control.robot import Robot
from mover6_control.control.status import Cause, MotionResult, StatusKey as K
import numpy as np

# After arrival the gain is at least this fraction of the error per control period (rad_per_s).
FINE_GAIN_PER_TICK = 0.25


class MotionTicks:
    """The per-state ticks of a motion of one arm's controller (module docstring)."""

    def __init__(self, robot: Robot, core_state: CoreState,
                 driver_compensation: DriverCompensation):
        """Tick ``robot``'s motions, stepping ``core_state``, behind ``driver_compensation``."""
        self.robot = robot
        self.core_state = core_state
        self.driver_compensation = driver_compensation

    def executing(self, now: float) -> Optional[np.ndarray]:
        """Follow the plan's reference; on to stopping (path error) or settling (its end)."""
        shared = self.core_state
        t = self.robot.follow(now, shared.speed_scaling)
        q_ref, qd_ref = self.robot.reference
        shared.waypoint = self.robot.plan.waypoints_reached(t)
        worst = float(np.max(np.abs(self.robot.error)))
        if worst > shared.config.path_tolerance:
            self.robot.give(plan_stop(q_ref, qd_ref, shared.config.law.a_max), now)
            reason = (f'tracking error {worst:.3f} rad above path tolerance '
                      f'{shared.config.path_tolerance} rad')
            shared.result = {K.RESULT: MotionResult.ABORTED, K.CAUSE: Cause.PATH_TOLERANCE,
                             K.REASON: reason}
            shared.step(sm.PATH_ERROR, 'WARN', f'aborting motion {shared.motion_id}: {reason}')
            return self.stopping(now)
        if t >= self.robot.plan.duration:
            shared.t_settle = now
            shared.step(sm.REFERENCE_DONE, 'OK', f'motion {shared.motion_id}: settling')
            return self.settling(now)
        return self.robot.command(shared.config.position_gain, shared.derived.velocity_limits)

    def settling(self, now: float) -> Optional[np.ndarray]:
        """
        Converge on the goal: 'arrived' inside the goal tolerance, then on to the fine one.

        The result 'arrived' is reported when every joint is inside ``goal_tolerance`` (as it
        always was); the state stays settling, with a zero reference velocity, until every
        joint is inside the settle tolerance or ``settle_time`` has passed since the arrival,
        then the controller goes idle and holds with a zero command.
        """
        shared = self.core_state
        goal = self.robot.plan.q_goal
        self.robot.hold(goal)
        shared.waypoint = shared.waypoints_total
        worst = float(np.max(np.abs(self.robot.error)))
        if shared.arrived_at is None:
            if np.all(self._within(self.robot.goal_tolerances)):
                shared.arrived_at = now
                shared.result = {K.RESULT: MotionResult.ARRIVED,
                                 K.FINAL_JOINT_ERROR: f'{worst:.6f}'}
                shared.message = (f'motion {shared.motion_id} arrived (max joint error '
                                  f'{worst:.4f} rad); settling')
                shared.changed = True
            elif now - shared.t_settle > shared.config.settle_timeout:
                reason = (f'not within goal tolerance after {shared.config.settle_timeout} s '
                          f'(max joint error {worst:.4f} rad)')
                shared.result = {K.RESULT: MotionResult.ABORTED, K.CAUSE: Cause.GOAL_TOLERANCE,
                                 K.REASON: reason, K.FINAL_JOINT_ERROR: f'{worst:.6f}'}
                shared.step(sm.SETTLE_TIMEOUT, 'WARN', f'motion {shared.motion_id}: {reason}')
                return None
        if shared.arrived_at is not None:
            fine = np.all(self._within(shared.derived.settle_tolerance))
            if fine or now - shared.arrived_at >= shared.config.settle_time:
                if self.driver_compensation.active and np.any(self._in_flight() != 0.0):
                    # Settle time over: command zero until what is in flight has landed, so
                    # the arm is still once idle (the driver lags up to two cycles).
                    return np.zeros_like(goal)
                shared.result = {**shared.result, K.SETTLED_JOINT_ERROR: f'{worst:.6f}'}
                how = 'settled' if fine else f'settle time {shared.config.settle_time} s over'
                shared.step(sm.SETTLED, 'OK', f'motion {shared.motion_id} arrived; {how} '
                                              f'(max joint error {worst:.6f} rad); holding')
                return None
            return self._fine_command(now)
        return self.robot.command(shared.config.position_gain, shared.derived.velocity_limits)

    def _in_flight(self):
        """Return the motion (n,) [rad] commanded that the latest reading cannot show yet."""
        return self.driver_compensation.in_flight(self.robot.t_states)

    def _within(self, tol):
        """Return which joints are within ``tol`` (n,) of the goal, counting what still moves."""
        if self.driver_compensation.active:
            return self.robot.within(tol, self._in_flight())
        # Not arrived while still moving: where the arm will be two ticks from now must be
        # within tolerance too (a law that ends at full speed, such as the synchronised one,
        # would otherwise declare arrival and coast one tick past the goal).
        return self.robot.within(tol, 2.0 * self.core_state.derived.dt * self.robot.qd)

    def _fine_command(self, now):
        """
        Return the command that closes the last of the error after arrival (n,) [rad/s].

        rad_per_s: the closed loop with a gain of at least ``FINE_GAIN_PER_TICK`` per control
        period (the readings are fresh), so the error falls from the goal tolerance to the
        settle tolerance in a fraction of a second without overshoot. Behind a driver with a
        cycle (fraction_of_max on the vendor's driver, or a ``cycle_driver``: the CAN driver,
        either unit): the whole-tick pulses of ``DriverCompensation.tick_pulses``, since the
        readings are whole ticks two or three cycles old (the plain loop on them crept, and
        limit-cycled a wrist joint by a tick).
        """
        derived = self.core_state.derived
        if not self.driver_compensation.active:
            gain = max(derived.config.position_gain, FINE_GAIN_PER_TICK / derived.dt)
            return self.robot.command(gain, derived.velocity_limits)
        return self.driver_compensation.tick_pulses(now, self.robot, derived.velocity_limits)

    def stopping(self, now: float) -> Optional[np.ndarray]:
        """Follow the stop plan to rest; then at rest (None: the state machine moved on)."""
        shared = self.core_state
        t = self.robot.follow(now)
        qd_ref = self.robot.reference[1]
        if t >= self.robot.plan.duration:
            self.robot.drop_plan()
            result = shared.result.get(K.RESULT, MotionResult.STOPPED)
            shared.step(sm.AT_REST, 'OK' if result == MotionResult.STOPPED else 'WARN',
                        f'motion {shared.motion_id} {result}: at rest, holding')
            return None
        return qd_ref.copy()
