"""
The robot the controller drives: the Mover6 report's ``Robot`` class, as the controller's model.

A ``Robot`` holds its joints (``Joint``: name, limits, goal tolerance, encoder tick), what was
last measured of them, the demand it was given and the reference it follows:

- ``measure(now, names, positions, velocities)`` takes a /joint_states message's arrays and maps
  them to the joints BY NAME (other joints in the message, a gripper say, are ignored, as ROS
  controllers ignore the joints they do not drive); a missing or repeated name, arrays of
  different lengths or a non-finite value make the states invalid with that reason
  (``invalid_reason``);
- ``give(plan, now)`` hands it a demand: the ``MotionPlan`` of the selected velocity law
  (``planners.plan_motion``), which it then holds and follows; ``demand`` is the plan's
  goal and ``q_initial`` where the arm was when it was given;
- ``follow(now, scaling)`` takes the plan's reference at ``now``: the plan time advances by
  the time since the last call times the speed scaling factor (``speed_scaling``; None: 1),
  and the reference velocity is the plan's times that factor; ``command(gain, velocity_limits)``
  then gives this tick's command: that reference plus the closed-loop correction on the
  measured position (``commands.closed_loop_command``); ``hold(goal)`` follows a fixed goal
  instead.

The controller core (``controller_core``) owns one; the state machine (``state_machine``)
decides what it may do. The values are numpy arrays inside (one entry per joint, chain order);
``joints`` and ``joint(name)`` build ``Joint`` values of the present state on demand.

The Mover6 report's velocity laws (eq. 1-2, synchronised; eq. 16-18, trapezoidal) are the
controller's profiles, planned once for every use (``motion_plan.synchronised_segment``,
``motion_plan.trapezoid_segment``): the robot follows their plans and holds no copy of them.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence, TYPE_CHECKING

from mover6_control.control.commands import closed_loop_command
from mover6_control.control.joint import Joint
from mover6_control.control.motion_plan import MotionPlan
from mover6_control.control.speed_scaling import SpeedScaling
from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_positive
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

_JOINT_FIELDS = ('lower', 'upper', 'velocity_limit', 'acceleration_limit', 'goal_tolerance',
                 'q', 'qd', 'demand', 'q_initial')


class Robot:
    """A named arm: its joints in chain order, their measurement, demand and reference."""

    def __init__(self, name: str, joints: Sequence[Joint]):
        """Make a robot of ``joints`` (``Joint`` values, unique names) in chain order."""
        joints = tuple(joints)
        if not joints:
            raise InvalidInputError('a robot needs at least one joint')
        if not all(isinstance(j, Joint) for j in joints):
            raise InvalidInputError('Robot.joints must hold Joint values')
        names = [j.name for j in joints]
        if len(set(names)) != len(names):
            raise InvalidInputError(f'joint names repeat: {names}')
        self.name = str(name)
        self._names = tuple(names)
        self._index = {n: i for i, n in enumerate(names)}
        self._order_of = (None, None)   # (names of the last states, where each joint is in them)
        for field in _JOINT_FIELDS:
            setattr(self, '_' + field, np.array([getattr(j, field) for j in joints], float))
        self._tick = np.array([np.nan if j.encoder_tick is None else j.encoder_tick
                               for j in joints])
        self.t_states = None             # [s] when the latest valid states came (None: none)
        self.n_states = 0                # valid states taken so far
        self.invalid_reason = None       # why the latest states were refused (None: valid)
        self.conflict = None             # (until [s], why): the states are not to be trusted
        self.plan = None                 # the running MotionPlan (None: none)
        self.t_plan = 0.0                # [s] when it started
        self.plan_time = 0.0             # [s] how far into the plan the reference is
        self._t_follow = 0.0             # [s] when the plan time was last advanced
        self.reference = None            # (q_ref, qd_ref) followed at the last command
        self.commanded = np.zeros(len(joints))   # [rad/s] the last command

    @classmethod
    def from_arm(cls, arm: ArmModel, goal_tolerance: float | Sequence[float] = 0.002,
                 acceleration_limit: float = math.inf,
                 encoder_ticks: Optional[Sequence[float]] = None) -> Robot:
        """Return a robot at rest at q = 0 with the names and limits of an ``ArmModel``."""
        n = arm.n_joints
        tol = np.broadcast_to(np.asarray(goal_tolerance, float), (n,))
        ticks = [None] * n if encoder_ticks is None else list(encoder_ticks)
        joints = tuple(
            Joint(name, float(lo), float(hi), float(v), acceleration_limit=acceleration_limit,
                  goal_tolerance=float(t), encoder_tick=tick)
            for name, lo, hi, v, t, tick in zip(arm.joint_names, arm.lower, arm.upper,
                                                arm.velocity_limits, tol, ticks))
        return cls(arm.name, joints)

    # --- the joints ---------------------------------------------------------------------------

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return len(self._names)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Return the joint names in chain order."""
        return self._names

    def joint(self, name: str) -> Joint:
        """Return the ``Joint`` called ``name`` as it is now; raise when there is none."""
        if name not in self._index:
            raise InvalidInputError(f'no joint "{name}" (joints: {list(self._names)})')
        i = self._index[name]
        tick = None if np.isnan(self._tick[i]) else float(self._tick[i])
        return Joint(name, encoder_tick=tick,
                     **{field: float(getattr(self, '_' + field)[i]) for field in _JOINT_FIELDS})

    @property
    def joints(self) -> tuple[Joint, ...]:
        """Return every ``Joint`` as it is now, in chain order."""
        return tuple(self.joint(name) for name in self._names)

    @property
    def q(self) -> np.ndarray:
        """Return the measured positions (n,) [rad]."""
        return self._q.copy()

    @property
    def qd(self) -> np.ndarray:
        """Return the measured velocities (n,) [rad/s]."""
        return self._qd.copy()

    @property
    def demand(self) -> np.ndarray:
        """Return the demanded positions (n,) [rad]."""
        return self._demand.copy()

    @property
    def q_initial(self) -> np.ndarray:
        """Return the positions (n,) [rad] measured when the demand was set."""
        return self._q_initial.copy()

    @property
    def lower(self) -> np.ndarray:
        """Return the lower position limits (n,) [rad]."""
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """Return the upper position limits (n,) [rad]."""
        return self._upper.copy()

    @property
    def velocity_limits(self) -> np.ndarray:
        """Return the velocity limits (n,) [rad/s]."""
        return self._velocity_limit.copy()

    @property
    def acceleration_limits(self) -> np.ndarray:
        """Return the acceleration limits (n,) [rad/s^2] (inf: none)."""
        return self._acceleration_limit.copy()

    @property
    def goal_tolerances(self) -> np.ndarray:
        """Return the goal tolerances (n,) [rad]."""
        return self._goal_tolerance.copy()

    @property
    def encoder_ticks(self) -> Optional[np.ndarray]:
        """Return the encoder ticks (n,) [rad] of a whole-tick driver, None for a velocity one."""
        return None if np.any(np.isnan(self._tick)) else self._tick.copy()

    def set_limits(self, goal_tolerance: Sequence[float], acceleration_limit: float,
                   encoder_ticks: Optional[Sequence[float]] = None) -> None:
        """Give every joint its goal tolerance (n,) [rad], acceleration limit and encoder tick."""
        tol = as_positive(goal_tolerance, 'goal_tolerance', self.n_joints)
        acc = np.broadcast_to(np.asarray(acceleration_limit, float), (self.n_joints,)).copy()
        if not np.all(acc > 0.0):
            raise InvalidInputError(f'acceleration limits must be > 0, got {acc.tolist()}')
        ticks = (np.full(self.n_joints, np.nan) if encoder_ticks is None
                 else as_positive(encoder_ticks, 'encoder_ticks', self.n_joints))
        self._goal_tolerance, self._acceleration_limit, self._tick = tol, acc, ticks

    # --- the controller's model: measurement ---------------------------------------------------

    def measure(self, now: float, names: Sequence[str], positions: Sequence[float],
                velocities: Optional[Sequence[float]] = None) -> None:
        """
        Take measured ``positions`` [rad] and ``velocities`` [rad/s] of the joints ``names``.

        Mapped by name, in any order; ``velocities`` may be empty or None (taken as zero).
        Raises ``InvalidInputError`` (and keeps the reason in ``invalid_reason``: the states are
        invalid until the next valid ones) when a joint is missing, a name is repeated, the
        arrays differ in length or a value is not finite. Other joints (a gripper) are ignored.
        """
        try:
            q, qd = self._by_name(names, positions, velocities)
        except InvalidInputError as err:
            self.invalid_reason = str(err)
            raise
        self._q, self._qd = q, qd
        self.t_states = float(now)
        self.invalid_reason = None
        self.n_states += 1

    def _by_name(self, names, positions, velocities):
        positions = np.asarray(positions, dtype=float).ravel()
        velocities = (np.zeros(0) if velocities is None
                      else np.asarray(velocities, dtype=float).ravel())
        if len(positions) != len(names):
            raise InvalidInputError(
                f'joint_states has {len(names)} names but {len(positions)} positions')
        if len(velocities) and len(velocities) != len(names):
            raise InvalidInputError(
                f'joint_states has {len(names)} names but {len(velocities)} velocities')
        # A sender names the same joints every time (100 messages a second): their order is
        # looked up once per list of names, not per message.
        names = tuple(names)
        if names != self._order_of[0]:
            self._order_of = (names, self._order(names))
        order = self._order_of[1]
        q = positions[order]
        qd = velocities[order] if len(velocities) else np.zeros(self.n_joints)
        if not (np.isfinite(q).all() and np.isfinite(qd).all()):
            raise InvalidInputError('joint_states has non-finite values')
        return q, qd

    def _order(self, names):
        """Return where each joint of the chain is in ``names``; raise when one is not there."""
        names = [str(name) for name in names]
        problems = []
        missing = [n for n in self._names if n not in names]
        if missing:
            problems.append(f'lacks joints {missing}')
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            problems.append(f'repeats joints {repeated}')
        if problems:
            raise InvalidInputError(f'joint_states {", ".join(problems)} (has {names})')
        return np.array([names.index(n) for n in self._names], dtype=np.intp)

    @property
    def measured(self) -> bool:
        """Return True once valid states came (since the last ``forget_states``)."""
        return self.t_states is not None

    def forget_states(self) -> None:
        """Forget the measurement (after a fault): wait for fresh states again."""
        self.t_states = None

    def states_problem(self, now: float, timeout: float) -> Optional[str]:
        """Return why the states cannot be used at ``now`` [s] (invalid, or stale), or None."""
        if self.invalid_reason is not None:
            return f'invalid /joint_states: {self.invalid_reason}'
        if self.conflict is not None and now < self.conflict[0]:
            return self.conflict[1]
        if self.t_states is not None and now - self.t_states > timeout:
            return (f'/joint_states stale: last valid {now - self.t_states:.3f} s ago '
                    f'(timeout {timeout} s)')
        return None

    # --- the controller's model: demand, reference, command ------------------------------------

    def give(self, plan: MotionPlan, now: float) -> None:
        """Follow ``plan`` (a ``MotionPlan``) from ``now`` [s]; its goal becomes the demand."""
        self.plan, self.t_plan = plan, float(now)
        self.plan_time, self._t_follow = 0.0, float(now)
        self._demand, self._q_initial = np.array(plan.q_goal, dtype=float), self._q.copy()

    def drop_plan(self) -> None:
        """Stop following any plan (the reference goes too)."""
        self.plan, self.reference = None, None

    def follow(self, now: float, scaling: Optional[SpeedScaling] = None) -> float:
        """
        Take the plan's reference at ``now`` [s] as the one to follow; return the plan time.

        The plan time advances by ``now`` minus the last call's time at ``scaling``'s factor
        (``SpeedScaling.advance``); with None it is the time since the plan was given.
        """
        dt = max(now - self._t_follow, 0.0)
        self._t_follow = max(self._t_follow, float(now))
        if scaling is None:
            self.plan_time = max(float(now) - self.t_plan, 0.0)
            self.reference = self.plan.sample(self.plan_time)
        else:
            self.plan_time, q_ref, qd_ref = scaling.advance(self.plan_time, dt,
                                                            self.plan.sample)
            self.reference = (q_ref, qd_ref)
        return self.plan_time

    def hold(self, goal: np.ndarray) -> None:
        """Follow a fixed ``goal`` (n,) [rad] at rest (after the plan's end)."""
        goal = np.asarray(goal, dtype=float)
        self.reference = (goal, np.zeros_like(goal))

    @property
    def error(self) -> np.ndarray:
        """Return the reference minus the measured positions (n,) [rad] (zero without one)."""
        if self.reference is None:
            return np.zeros(self.n_joints)
        return self.reference[0] - self._q

    def within(self, tolerance: np.ndarray, still_to_move: np.ndarray) -> np.ndarray:
        """
        Return which joints (n,) bool are within ``tolerance`` (n,) [rad] of the reference.

        Both the measured position and the position after ``still_to_move`` (n,) [rad] (what
        the joint is still going to move) must be within it.
        """
        error = self.error
        return (np.abs(error) <= tolerance) & (np.abs(error - still_to_move) <= tolerance)

    def command(self, gain: float, velocity_limits: np.ndarray,
                q: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return the velocities (n,) [rad/s] to command now, from the law's reference.

        ``qd_ref + gain (q_ref - q)`` within ``velocity_limits`` (n,) [rad/s], one common factor
        (``commands.closed_loop_command``); ``q`` defaults to the measured position (the
        vendor driver passes where the arm will be once what is in flight has landed).
        """
        q_ref, qd_ref = self.reference
        return closed_loop_command(q_ref, qd_ref, self._q if q is None else q, gain,
                                   velocity_limits)
