"""
The controller without ROS: joint states and demands in, one velocity command per tick out.

``ControllerCore`` owns the model of the arm, a ``Robot`` (``control.robot``: its ``Joint``s
with limits, goal tolerance and encoder tick, the measured states, the running ``MotionPlan``
of the selected velocity law and its reference), the state machine (``state_machine``), which
decides from what the robot reports, and the safety checks. The node hands /joint_states to the
robot by name (``on_named_joint_states``, which faults on invalid ones), plans and starts each
demand in its demand thread (``demand_intake``: ``check_demand``, ``snapshot``,
``prepare_demand``, ``commit_demand``, or ``reject`` with the reason), calls ``request_stop``
and ``reset`` from its callbacks and ``tick(now)`` from its tick thread, and publishes what
comes back; every tick asks the robot for its command (``Robot.command``). Time is always an
argument [s], so tests drive it with synthetic time and no sleeps (``test/core_testing.py``
makes the node's calls in one thread).

Safety, per tick: joint states older than ``state_timeout``, or reported incomplete or
non-finite, give a zero command and the fault state at once; a fresh valid state recovers to
idle. So does a tick that raises, or a law's command that is not finite (never sent: the
reason goes on the status); ``tick`` itself never raises. Entering idle, finishing a stop and
entering fault give an explicit zero command (the vendor driver keeps the last command
forever). A demand that is empty, non-finite or outside
the joint limits raises ``InvalidInputError`` and leaves the running motion untouched; a valid
one while moving replaces the motion, starting from the present reference and its velocity, so
the command does not jump. No joint is commanded further past a limit.

Behind a driver with a cycle (``jog_units`` 'fraction_of_max', the Mover6's vendor driver, or
``cycle_driver``) the commands are compensated for its whole ticks and for what is still in
flight (``driver_compensation``).

One concept a module: this one holds the inputs and the tick; its parts are the settings
(``controller_config``), the demand protocol (``demand_intake``), jogging (``jogging``), the
per-state ticks of a motion (``motion_ticks``) and the status (``status_report``). What the
parts share lives in one record, the core's ``core_state`` (``core_state.CoreState``: the state
machine's state and message, the motion, how it ended, the settings in force and pending); what
only jogging keeps, in ``jog_session``; the arm's model, in ``robot``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

from mover6_control.control import state_machine as sm
from mover6_control.control.commands import guard_position_limits, to_jog_units
from mover6_control.control.controller_config import ControllerConfig, derive_config
from mover6_control.control.core_state import CoreState
from mover6_control.control.demand_intake import DemandIntake
from mover6_control.control.driver_compensation import DriverCompensation
from mover6_control.control.jogging import Jogging, JogSession
from mover6_control.control.motion_plan import MotionPlan, plan_stop
from mover6_control.control.motion_ticks import MotionTicks
from mover6_control.control.robot import Robot
from mover6_control.control.status import Cause, MotionResult, StatusKey as K
from mover6_control.control.status_report import StatusReport
from mover6_control.kinematics.arm import ArmModel
import numpy as np


@dataclass(frozen=True, eq=False)
class TickOutput:
    """
    One tick's result.

    ``qd`` (n,) [rad/s] is the command; ``jog`` (n,) the same in the configured JointJog units;
    ``status_changed`` says the state, result or motion changed since the last tick.
    """

    qd: np.ndarray
    jog: np.ndarray
    state: str
    status_changed: bool


class ControllerCore(DemandIntake, Jogging, MotionTicks, StatusReport):
    """The controller's logic for one arm; see the module docstring."""

    def __init__(self, arm: ArmModel, config: Optional[ControllerConfig] = None):
        """Make a controller for ``arm`` (an ``ArmModel``) with ``config``."""
        self.arm = arm
        self.robot = Robot.from_arm(arm)  # the model: joints, states, demand, reference
        # A driver with a cycle behind the commands (control.driver_compensation).
        self.driver_compensation = DriverCompensation(arm.n_joints)
        derived = derive_config(self.arm, ControllerConfig() if config is None else config)
        # What the parts share: the state machine, the motion, its result, the settings.
        self.core_state = CoreState(derived)
        self._apply(derived)
        self.jog_session = JogSession()  # jogging's own state (control.jogging)
        # A callable(plan) that raises on a colliding motion (collision_guard.CollisionGuard);
        # the node sets it. None: no collision check.
        self.collision_guard = None
        self.tick_failures = 0           # ticks in a row that raised (a fault each)

    def _apply(self, derived):
        """Install a ``DerivedConfig``: the robot's limits, the driver's ticks, then it whole."""
        self.robot.set_limits(derived.goal_tolerance, derived.config.law.a_max, derived.ticks)
        self.driver_compensation.configure(derived)
        self.core_state.derived = derived

    @property
    def config(self) -> ControllerConfig:
        """Return the ``ControllerConfig`` in force (``core_state.derived``'s)."""
        return self.core_state.derived.config

    def check_config(self, config: ControllerConfig) -> None:
        """Raise ``InvalidInputError`` saying why ``config`` cannot drive this arm."""
        derive_config(self.arm, config)

    def reconfigure(self, config: ControllerConfig) -> bool:
        """
        Use ``config`` from now on, or from the end of the running motion; return True if now.

        Idle (or waiting, or in fault) it applies at once: tolerances, velocity limits, the
        control period, the driver's ticks. While executing, settling or stopping it is kept
        pending (``pending_parameters`` in the status) and applied on the first tick after the
        motion ends, so a motion runs with one config from start to end; a later call replaces
        a pending config. Raises ``InvalidInputError`` (nothing changed) when it does not fit.
        """
        derived = derive_config(self.arm, config)
        self.core_state.changed = True
        if self.core_state.state in sm.MOVING_STATES:
            self.core_state.pending = derived
            return False
        self.core_state.pending = None
        self._apply(derived)
        return True

    @property
    def pending_config(self) -> Optional[ControllerConfig]:
        """Return the config waiting for the running motion to end (None when none)."""
        return None if self.core_state.pending is None else self.core_state.pending.config

    @property
    def goal_tolerance(self) -> np.ndarray:
        """Return the goal tolerance (n,) [rad] in use (at least one tick in fraction_of_max)."""
        return self.robot.goal_tolerances

    # --- inputs -------------------------------------------------------------------------------

    @property
    def state(self) -> str:
        """Return the current state name (``state_machine.STATES``)."""
        return self.core_state.state

    @property
    def motion_id(self) -> int:
        """Return the id of the latest accepted demand (0 before any)."""
        return self.core_state.motion_id

    @property
    def plan(self) -> Optional[MotionPlan]:
        """Return the running ``MotionPlan`` (None when none)."""
        return self.robot.plan

    def on_named_joint_states(self, now: float, names: Sequence[str],
                              positions: Sequence[float],
                              velocities: Optional[Sequence[float]] = None) -> None:
        """
        Hand a /joint_states message's names, positions and velocities to the robot (by name).

        Other joints are ignored. A missing or repeated name, arrays of different lengths or a
        non-finite value raise ``InvalidInputError`` and make the states invalid with that
        reason (fault).
        """
        self.robot.measure(now, names, positions, velocities)

    def distrust_states(self, now: float, reason: str, hold: float) -> None:
        """Refuse the joint states for ``hold`` [s] from ``now`` for ``reason``: fault, hold."""
        self.robot.conflict = (float(now) + float(hold), str(reason))

    def request_stop(self, now: float) -> tuple[bool, str]:
        """Decelerate to rest and hold; return ``(True, message)`` or why nothing moved."""
        if self.core_state.state not in (sm.EXECUTING, sm.SETTLING, sm.JOGGING):
            return True, f'not moving ({self.core_state.state}); command is zero'
        ref = self.robot.reference
        q_ref, qd_ref = ref if ref is not None else (self.robot.q, self.robot.commanded)
        self.robot.give(plan_stop(q_ref, qd_ref, self.config.law.a_max), now)
        self.core_state.result = {K.RESULT: MotionResult.STOPPED,
                                  K.CAUSE: Cause.STOP_REQUESTED, K.REASON: 'stop requested'}
        self._set(sm.STOP, 'OK', f'stopping motion {self.core_state.motion_id} on request')
        return True, f'stopping within {self.robot.plan.duration:.2f} s'

    def reset(self, now: float) -> None:
        """Leave fault: wait for fresh joint states again."""
        if self.core_state.state == sm.FAULT:
            self.robot.forget_states()
            self._set(sm.RESET, 'WARN', 'reset: waiting for /joint_states')

    # --- the tick -----------------------------------------------------------------------------

    def tick(self, now: float) -> TickOutput:
        """
        Return the ``TickOutput`` at ``now`` [s]: check the states, run the law.

        Never raises: an exception inside the tick, or a command that is not finite (from any
        law), is a fault (``_tick_fault``): a zero command, the reason on the status, and
        recovery as from stale states (fresh valid states after it). ``tick_failures`` counts
        the ticks in a row that raised, so a node can tell a tick that cannot run at all.
        """
        try:
            out = self._tick(now)
        except Exception as err:  # noqa: B902 - whatever breaks a tick stops the arm
            self.tick_failures += 1
            return self._tick_fault(now, f'tick failed: {type(err).__name__}: {err}')
        self.tick_failures = 0
        return out

    def _tick_fault(self, now, reason):
        """Fault at ``now``: drop the motion or jog, a zero command, ``reason`` on the status."""
        if self.core_state.state in sm.MOVING_STATES:
            self.core_state.result = {K.RESULT: MotionResult.FAULT, K.REASON: reason}
        self.robot.drop_plan()
        self.core_state.t_fault = now
        self._set(sm.TICK_FAULT, 'ERROR', reason)
        zero = np.zeros(self.arm.n_joints)
        self.robot.commanded = zero
        return TickOutput(zero, zero.copy(), self.core_state.state, True)

    def _tick(self, now):
        self._check_states(now)
        shared = self.core_state
        state = shared.state
        qd = None
        if state == sm.EXECUTING:
            qd = self._tick_executing(now)
        elif state == sm.SETTLING:
            qd = self._tick_settling(now)
        elif state == sm.STOPPING:
            qd = self._tick_stopping(now)
        elif state == sm.JOGGING:
            qd = self._tick_jogging(now)
        if qd is None or shared.state not in sm.MOVING_STATES:
            qd = np.zeros(self.arm.n_joints)
            self.robot.reference = None
        else:
            if (self.driver_compensation.active and shared.state in (sm.EXECUTING, sm.SETTLING)
                    and shared.arrived_at is None):     # after arrival: whole-tick pulses
                qd = self.driver_compensation.whole_ticks(now, qd, self.robot)
            qd = guard_position_limits(qd, self.robot.q, self.robot.lower, self.robot.upper,
                                       shared.derived.dt)
            if not np.all(np.isfinite(qd)):      # never sent: no driver may receive a NaN
                return self._tick_fault(now, f'non-finite command {np.asarray(qd).tolist()} '
                                             f'while {state}: not sent')
        self.driver_compensation.end_tick(now, qd, self.robot.n_states)
        self.robot.commanded = qd
        jog = to_jog_units(qd, self.arm.velocity_limits, self.config.jog_units,
                           self.config.speed_override)
        if shared.pending is not None and shared.state not in sm.MOVING_STATES:
            self._apply(shared.pending)      # the motion ended: the new config now
            shared.pending = None
            shared.changed = True
        changed, shared.changed = shared.changed, False
        return TickOutput(qd, jog, shared.state, changed)

    def _check_states(self, now):
        shared = self.core_state
        if not self.robot.measured:
            if self.robot.invalid_reason is not None:
                message = f'waiting for valid /joint_states: {self.robot.invalid_reason}'
                if message != shared.message:
                    shared.message, shared.changed = message, True
            return
        reason = self.robot.states_problem(now, self.config.state_timeout)
        if reason is not None:
            if shared.state != sm.FAULT and sm.accepts(shared.state, sm.STATES_INVALID):
                if shared.state in sm.MOVING_STATES:
                    shared.result = {K.RESULT: MotionResult.FAULT, K.CAUSE: Cause.STATES_INVALID,
                                     K.REASON: reason}
                self.robot.drop_plan()
                shared.t_fault = now
                self._set(sm.STATES_INVALID, 'ERROR', reason)
            return
        if shared.state == sm.WAITING_FOR_STATES:
            self._set(sm.STATES_VALID, 'OK', 'joint states received; idle')
        elif shared.state == sm.FAULT and self.robot.t_states > shared.t_fault:
            self._set(sm.STATES_VALID, 'OK', 'valid joint states again; idle')

    def _set(self, event, level, message):
        """Step the state machine by ``event``; the status says ``message`` at ``level``."""
        shared = self.core_state
        shared.state = sm.step(shared.state, event)
        shared.level, shared.message = level, message
        shared.changed = True
