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

One class built from parts, each a class made here with what it needs and that a test builds
alone (one concept a module): ``core_settings.CoreSettings`` (the config in force and pending),
``states_check.StatesCheck`` (the states' check opening each tick), ``demand_intake.DemandIntake``
(the demand protocol), ``jogging.Jogging``, ``motion_ticks.MotionTicks`` (the per-state ticks of
a motion) and ``status_report.StatusReport``. What they share is one record they are each given,
``core_state.CoreState`` (the state machine's state and message, the motion, how it ended, the
settings in force and pending, the collision guard); the arm's model is the ``Robot`` they are
each given. This class holds the inputs, the stop and reset, and the tick that dispatches to
the part of the state; its other methods hand the call to the part named in their docstring.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence

from mover6_control.control import state_machine as sm
from mover6_control.control.commands import guard_position_limits, to_jog_units
from mover6_control.control.controller_config import ControllerConfig, derive_config
from mover6_control.control.core_settings import CoreSettings
from mover6_control.control.core_state import CoreState
from mover6_control.control.demand_intake import (DemandIntake, NotAcceptingError,
                                                  PendingDemand, Planner, Snapshot)
from mover6_control.control.driver_compensation import DriverCompensation
from mover6_control.control.jogging import Jogging, JogSession
from mover6_control.control.motion_plan import MotionPlan, plan_stop
from mover6_control.control.motion_ticks import MotionTicks
from mover6_control.control.profiles import LawConfig
from mover6_control.control.robot import Robot
from mover6_control.control.speed_scaling import SpeedScaling
from mover6_control.control.states_check import StatesCheck
from mover6_control.control.status import Cause, MotionResult, StatusKey as K
from mover6_control.control.status_report import Status, StatusReport
from mover6_control.control.timed_plan import Timing
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


class ControllerCore:
    """The controller's logic for one arm, built from its parts; see the module docstring."""

    def __init__(self, arm: ArmModel, config: Optional[ControllerConfig] = None):
        """Make a controller for ``arm`` (an ``ArmModel``) with ``config``."""
        self.arm = arm
        self.robot = Robot.from_arm(arm)  # the model: joints, states, demand, reference
        # A driver with a cycle behind the commands (control.driver_compensation).
        self.driver_compensation = DriverCompensation(arm.n_joints)
        derived = derive_config(arm, ControllerConfig() if config is None else config)
        # What the parts share: the state machine, the motion, its result, the settings.
        self.core_state = CoreState(derived)
        self.settings = CoreSettings(arm, self.robot, self.driver_compensation, self.core_state)
        self.settings.apply(derived)
        self.states_check = StatesCheck(self.robot, self.core_state)
        self.demands = DemandIntake(arm, self.robot, self.core_state)
        self.jogging = Jogging(arm, self.robot, self.core_state)
        self.motions = MotionTicks(self.robot, self.core_state, self.driver_compensation)
        self.report = StatusReport(arm, self.robot, self.core_state, self.jogging.session)
        self.tick_failures = 0           # ticks in a row that raised (a fault each)

    # --- settings (core_settings.CoreSettings) ------------------------------------------------

    @property
    def config(self) -> ControllerConfig:
        """Return the ``ControllerConfig`` in force (``core_state.derived``'s)."""
        return self.core_state.config

    def check_config(self, config: ControllerConfig) -> None:
        """Raise ``InvalidInputError`` saying why ``config`` cannot drive this arm."""
        self.settings.check(config)

    def reconfigure(self, config: ControllerConfig) -> bool:
        """Use ``config`` now (True) or once the motion ends: ``CoreSettings.reconfigure``."""
        return self.settings.reconfigure(config)

    @property
    def pending_config(self) -> Optional[ControllerConfig]:
        """Return the config waiting for the running motion to end (None when none)."""
        return self.settings.pending_config

    @property
    def goal_tolerance(self) -> np.ndarray:
        """Return the goal tolerance (n,) [rad] in use (at least one tick in fraction_of_max)."""
        return self.robot.goal_tolerances

    @property
    def collision_guard(self) -> Optional[Callable[[MotionPlan], None]]:
        """
        Return the collision check of demands and jogs (None: none).

        A callable(plan) that raises on a colliding motion (``collision_guard.CollisionGuard``,
        whose ``veto`` jogging uses); the node sets it.
        """
        return self.core_state.collision_guard

    @collision_guard.setter
    def collision_guard(self, guard: Optional[Callable[[MotionPlan], None]]) -> None:
        self.core_state.collision_guard = guard

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

    @property
    def jog_session(self) -> JogSession:
        """Return what jogging keeps between commands and ticks (``Jogging.session``)."""
        return self.jogging.session

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
        shared = self.core_state
        if shared.state not in (sm.EXECUTING, sm.SETTLING, sm.JOGGING):
            return True, f'not moving ({shared.state}); command is zero'
        ref = self.robot.reference
        q_ref, qd_ref = ref if ref is not None else (self.robot.q, self.robot.commanded)
        self.robot.give(plan_stop(q_ref, qd_ref, shared.config.law.a_max), now)
        shared.result = {K.RESULT: MotionResult.STOPPED,
                         K.CAUSE: Cause.STOP_REQUESTED, K.REASON: 'stop requested'}
        shared.step(sm.STOP, 'OK', f'stopping motion {shared.motion_id} on request')
        return True, f'stopping within {self.robot.plan.duration:.2f} s'

    def request_speed_scaling(self, factor: object) -> float:
        """
        Ask for the speed scaling ``factor`` (0 pause .. 1 the plan's timing); return it.

        The effective factor ramps to it within the acceleration limit (``speed_scaling``);
        a factor that is not finite or outside [0, 1] raises ``InvalidInputError`` and the
        last valid one stays.
        """
        factor = self.core_state.speed_scaling.request(factor)
        self.core_state.changed = True
        return factor

    @property
    def speed_scaling(self) -> SpeedScaling:
        """Return the speed scaling of motions (its ``factor`` and ``target``)."""
        return self.core_state.speed_scaling

    def reset(self, now: float) -> None:
        """Leave fault: wait for fresh joint states again."""
        if self.core_state.state == sm.FAULT:
            self.robot.forget_states()
            self.core_state.step(sm.RESET, 'WARN', 'reset: waiting for /joint_states')

    # --- demands (demand_intake.DemandIntake) -------------------------------------------------

    def snapshot(self) -> Snapshot:
        """Return the ``Snapshot`` a demand is planned from: ``DemandIntake.snapshot``."""
        return self.demands.snapshot()

    def check_demand(self, waypoints: np.ndarray) -> np.ndarray:
        """Return the demand (N, n) [rad] inside the limits: ``DemandIntake.check_demand``."""
        return self.demands.check_demand(waypoints)

    def prepare_demand(self, now: float, waypoints: np.ndarray, snapshot: Snapshot,
                       demand_id: str = '', timing: Optional[Timing] = None,
                       profile: str = '', planner: Optional[Planner] = None) -> PendingDemand:
        """Check and plan a demand from ``snapshot``: ``DemandIntake.prepare_demand``."""
        return self.demands.prepare_demand(now, waypoints, snapshot, demand_id, timing,
                                           profile, planner)

    def law_for(self, profile: str = '', config: Optional[ControllerConfig] = None) -> LawConfig:
        """Return a demand's law with its own ``profile``: ``DemandIntake.law_for``."""
        return self.demands.law_for(profile, config)

    def is_current(self, pending: PendingDemand) -> bool:
        """Return whether ``pending`` still fits: ``DemandIntake.is_current``."""
        return self.demands.is_current(pending)

    def commit_demand(self, pending: PendingDemand, start: Optional[float] = None) -> int:
        """Start a prepared demand; return its motion id: ``DemandIntake.commit_demand``."""
        return self.demands.commit_demand(pending, start)

    def reject(self, now: float, reason: str, demand_id: str = '') -> None:
        """Note a refused demand in the status: ``DemandIntake.reject``."""
        self.demands.reject(now, reason, demand_id)

    def refusal(self) -> Optional[NotAcceptingError]:
        """Return why no demand is taken now (None: one is): ``DemandIntake.refusal``."""
        return self.demands.refusal()

    # --- jogging (jogging.Jogging) ------------------------------------------------------------

    def on_twist(self, now: float, stamp: float, linear: Sequence[float],
                 angular: Sequence[float], frame: str = 'base_link') -> None:
        """Take a flange twist [m/s, rad/s] stamped ``stamp``: ``Jogging.on_twist``."""
        self.jogging.on_twist(now, stamp, linear, angular, frame)

    def on_joint_jog(self, now: float, stamp: float, names: Sequence[str],
                     velocities: Sequence[float]) -> None:
        """Take joint velocities [rad/s] by name: ``Jogging.on_joint_jog``."""
        self.jogging.on_joint_jog(now, stamp, names, velocities)

    def note_jog_refused(self, reason: str) -> None:
        """Keep why a jog command was refused: ``Jogging.note_jog_refused``."""
        self.jogging.note_jog_refused(reason)

    # --- the status (status_report.StatusReport) ----------------------------------------------

    def status(self) -> Status:
        """Return the ``Status`` to publish now: ``StatusReport.status``."""
        return self.report.status()

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
        shared = self.core_state
        if shared.state in sm.MOVING_STATES:
            shared.result = {K.RESULT: MotionResult.FAULT, K.REASON: reason}
        self.robot.drop_plan()
        shared.t_fault = now
        shared.step(sm.TICK_FAULT, 'ERROR', reason)
        zero = np.zeros(self.arm.n_joints)
        self.robot.commanded = zero
        return TickOutput(zero, zero.copy(), shared.state, True)

    def _tick(self, now):
        self.states_check.check(now)
        shared = self.core_state
        state = shared.state
        qd = None
        if state == sm.EXECUTING:
            qd = self.motions.executing(now)
        elif state == sm.SETTLING:
            qd = self.motions.settling(now)
        elif state == sm.STOPPING:
            qd = self.motions.stopping(now)
        elif state == sm.JOGGING:
            qd = self.jogging.tick(now)
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
        config = shared.config
        jog = to_jog_units(qd, self.arm.velocity_limits, config.jog_units,
                           config.speed_override)
        self.settings.apply_pending()     # the motion ended: a pending config now
        changed, shared.changed = shared.changed, False
        return TickOutput(qd, jog, shared.state, changed)
