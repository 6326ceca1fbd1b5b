"""
The controller without ROS: joint states and demands in, one velocity command per tick out.

``ControllerCore`` owns the state machine (``state_machine``), the running ``MotionPlan``
(``velocity_laws``) and the safety checks. The node calls ``on_joint_states``,
``on_invalid_states``, ``on_demands``, ``request_stop`` and ``reset`` from its callbacks and
``tick(now)`` from its timer, and publishes what comes back. Time is always an argument [s], so
tests drive it with synthetic time and no sleeps.

Safety, per tick: joint states older than ``state_timeout``, or reported incomplete or
non-finite, give a zero command and the fault state at once; a fresh valid state recovers to
idle. Entering idle, finishing a stop and entering fault give an explicit zero command (the
vendor driver keeps the last command forever). A demand that is empty, non-finite or outside
the joint limits raises ``InvalidInputError`` and leaves the running motion untouched; a valid
one while moving replaces the motion, starting from the present reference and its velocity, so
the command does not jump. No joint is commanded further past a limit.

``jog_units`` 'fraction_of_max' (the Mover6's vendor driver): the driver moves each joint by
whole encoder ticks per cycle (``driver_tick_size``, ``driver_cycle``), so a joint commanded
under one tick per cycle does not move at all (J5/J6: about 7 deg/s), and its position is only
known to a tick. Two things make the arm arrive anyway:

- dead-zone compensation (``velocity_laws.dead_zone_command``): a joint whose command is below
  ``min_jog_speed`` gets exactly that speed towards its error while the error exceeds half a
  tick, zero inside. Its readings lag the driver by up to two cycles, so such a joint moves in
  pulses: one driver cycle long (one tick), started on a fresh reading, then no new pulse until
  a reading that shows the pulse (two readings later; three after the law itself moved the
  joint). It never overshoots by what is still in flight, so it settles instead of oscillating.
- the goal tolerance of each joint is ``max(goal_tolerance, one tick)`` (reported in the
  status as ``goal_tolerance``), and the arm has arrived only when both the reading and the
  reading minus what was commanded since (from two cycles before it came: maybe in flight) are
  within it, so a joint still moving does not arrive on a stale reading and then drift out.

This assumes the readings come once per driver cycle (or less often) and that two and a half
control periods plus the delays of a reading and of a command stay under one driver cycle (at
100 Hz and 20 Hz: delays under 12 ms each). Beyond that (a reading 40 ms late) a pulse may
move two ticks, a wrist goal between two ticks may not settle, and the motion then ends
'aborted' after ``settle_timeout`` rather than 'arrived' out of tolerance.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Optional, Sequence

from mover6_control.control import state_machine as sm
from mover6_control.control.velocity_laws import (closed_loop_command, dead_zone_command,
                                                  driver_velocity_limits, guard_position_limits,
                                                  JOG_UNITS, LawConfig, min_jog_speed, MotionPlan,
                                                  plan_motion, plan_stop, to_jog_units)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, MOVER6_DRIVER_CYCLE, MOVER6_TICK_SIZE
from mover6_control.validation import as_positive
import numpy as np

# After arrival the gain is at least this fraction of the error per control period
# (rad_per_s) or per driver cycle (fraction_of_max, on the error minus what is in flight).
FINE_GAIN_PER_TICK = 0.25
FINE_GAIN_PER_CYCLE = 0.25


@dataclass(frozen=True)
class ControllerConfig:
    """
    The controller's settings (the node's parameters).

    ``goal_tolerance`` [rad] (scalar or (n,)): settled when every joint is this close.
    ``state_timeout`` [s]: joint states older than this are stale. ``position_gain`` [1/s]: the
    closed-loop gain on the position error. ``settle_timeout`` [s]: give up settling (result
    'aborted'). ``path_tolerance`` [rad]: a tracking error above it aborts the motion with a
    controlled stop. ``rate`` [Hz]: the tick rate, for the position-limit guard.
    ``jog_units``: 'rad_per_s' or 'fraction_of_max' (the vendor driver, which moves at
    ``value * max speed * speed_override``). 'fraction_of_max' only: ``driver_tick_size`` (n,)
    [rad] one encoder tick per joint and ``driver_cycle`` [s] the driver's cycle (defaults: the
    Mover6's), for the dead-zone compensation and the goal tolerance of at least one tick.
    ``settle_tolerance`` [rad]: after arriving (inside ``goal_tolerance``, result 'arrived')
    the controller keeps converging until every joint is this close (in 'fraction_of_max':
    one tick per joint, what the driver resolves) or ``settle_time`` [s] has passed, then
    holds with a zero command.
    """

    law: LawConfig = field(default_factory=LawConfig)
    goal_tolerance: object = 0.002
    state_timeout: float = 0.25
    position_gain: float = 2.0
    settle_timeout: float = 3.0
    path_tolerance: float = 0.3
    rate: float = 100.0
    jog_units: str = 'rad_per_s'
    speed_override: float = 0.25
    driver_tick_size: tuple = MOVER6_TICK_SIZE
    driver_cycle: float = MOVER6_DRIVER_CYCLE
    settle_tolerance: float = 0.0001
    settle_time: float = 1.0

    def __post_init__(self):
        """Check every setting."""
        for name in ('state_timeout', 'settle_timeout', 'path_tolerance', 'rate',
                     'settle_tolerance'):
            as_positive(getattr(self, name), name)
        if not (np.isfinite(self.settle_time) and self.settle_time >= 0.0):
            raise InvalidInputError(f'settle_time must be >= 0, got {self.settle_time}')
        if not (np.isfinite(self.position_gain) and self.position_gain >= 0.0):
            raise InvalidInputError(f'position_gain must be >= 0, got {self.position_gain}')
        tol = np.asarray(self.goal_tolerance, dtype=float)
        if not np.all(np.isfinite(tol)) or np.any(tol <= 0.0):
            raise InvalidInputError(f'goal_tolerance must be positive, got {tol.tolist()}')
        if self.jog_units not in JOG_UNITS:
            raise InvalidInputError(f'jog_units must be one of {JOG_UNITS}, got '
                                    f'"{self.jog_units}"')
        if not (0.0 < self.speed_override <= 1.0):
            raise InvalidInputError(f'speed_override must be in (0, 1], got '
                                    f'{self.speed_override}')
        ticks = np.asarray(self.driver_tick_size, dtype=float)
        if ticks.ndim != 1 or not ticks.size:
            raise InvalidInputError(f'driver_tick_size must be one value per joint, got '
                                    f'{self.driver_tick_size!r}')
        min_jog_speed(ticks, self.driver_cycle)          # raises on non-positive values
        object.__setattr__(self, 'driver_tick_size', tuple(float(t) for t in ticks))


def config_changes(old: ControllerConfig, new: ControllerConfig) -> list:
    """Return ``[(name, new value)]`` of the settings (law settings included) that differ."""
    changes = []
    for name in ControllerConfig.__dataclass_fields__:
        a, b = getattr(old, name), getattr(new, name)
        if name == 'law':
            changes += [(key, getattr(b, key)) for key in type(b).__dataclass_fields__
                        if getattr(a, key) != getattr(b, key)]
        elif not np.array_equal(np.asarray(a), np.asarray(b)):
            changes.append((name, b))
    return changes


@dataclass(frozen=True)
class Status:
    """What goes out on /controller/status: state, level, human message, named values."""

    state: str
    level: str
    message: str
    values: dict


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


@dataclass(frozen=True, eq=False)
class Snapshot:
    """
    What a demand is planned from, read once under the node's lock (``ControllerCore.snapshot``).

    ``state``; ``start`` = ``(q, qd)`` the plan starts from: the reference of the last tick and
    its velocity while moving, the measured position and None (rest) otherwise; ``moving``;
    ``motion_id`` of the latest accepted demand. Immutable, so planning from it outside the lock
    cannot see a tick change it halfway.
    """

    state: str
    start: tuple
    moving: bool
    motion_id: int


@dataclass(frozen=True, eq=False)
class PendingDemand:
    """A checked and planned demand not yet started (``ControllerCore.prepare_demand``)."""

    now: float
    waypoints: np.ndarray
    plan: MotionPlan
    moving: bool
    motion_id: int
    demand_id: str = ''
    config: Optional[ControllerConfig] = None   # the config it was planned with


class ControllerCore:
    """The controller's logic for one arm; see the module docstring."""

    def __init__(self, arm: ArmModel, config: Optional[ControllerConfig] = None):
        """Make a controller for ``arm`` (an ``ArmModel``) with ``config``."""
        self.arm = arm
        self.config = None
        self._pending_config = None      # applies when the running motion ends
        self._apply(self._derive(ControllerConfig() if config is None else config))
        n = arm.n_joints
        self._n_states = 0               # valid joint states received so far
        self._n_states_seen = 0          # ... as of the previous tick
        self._pulse_until = np.full(n, -np.inf)  # [s] end of each joint's one-tick pulse
        self._pulse_after = np.zeros(n, dtype=int)  # no new pulse before this many readings
        self._travel = np.zeros(n)       # [rad] integral of the commands sent
        self._state = sm.WAITING_FOR_STATES
        self._q = None
        self._qd_measured = None
        self._t_states = None
        self._bad_states = None          # reason why the latest states were rejected
        self._t_fault = None
        self._plan = None
        self._t_plan = 0.0
        self._ref = None                 # (q_ref, qd_ref) of the last tick
        self._qd_cmd = np.zeros(n)
        self._motion_id = 0
        self._waypoints_total = 0
        self._waypoint = 0
        self._t_settle = 0.0
        self._error = np.zeros(n)
        self._message = 'waiting for /joint_states'
        self._level = 'WARN'
        self._result = {}
        self._rejection = {}             # the last refused demand, until one is accepted
        self._arrived_at = None          # [s] when the running motion arrived (None: not yet)
        self._changed = True
        # A callable(plan) that raises on a colliding motion (collision_guard.CollisionGuard);
        # the node sets it. None: no collision check.
        self.collision_guard = None

    def _derive(self, config):
        """
        Return ``config`` and what follows from it, for ``arm``; raise when they do not fit.

        Reads nothing of the controller's state, changes nothing: ``_apply`` installs it.
        """
        if not isinstance(config, ControllerConfig):
            raise InvalidInputError(f'config must be a ControllerConfig, got {config!r}')
        arm, n = self.arm, self.arm.n_joints
        tol = np.broadcast_to(np.asarray(config.goal_tolerance, float), (n,)).copy()
        settle_tol = np.minimum(np.full(n, config.settle_tolerance), tol)
        vlim = driver_velocity_limits(arm.velocity_limits, config.jog_units,
                                      config.speed_override)
        ticks = min_speed = None
        if config.jog_units == 'fraction_of_max':
            # The driver's tick sizes: the goal tolerance is at least one tick.
            ticks = np.asarray(config.driver_tick_size, dtype=float)
            if ticks.shape != (n,):
                raise InvalidInputError(f'driver_tick_size has {ticks.size} values for '
                                        f'{n} joints: give one per joint')
            min_speed = min_jog_speed(ticks, config.driver_cycle)
            slow = np.flatnonzero(min_speed > vlim)
            if slow.size:
                names = ', '.join(f'{arm.joint_names[i]} (needs {min_speed[i]:.3f} rad/s, '
                                  f'can {vlim[i]:.3f})' for i in slow)
                raise InvalidInputError(
                    f'at speed_override {config.speed_override} the driver cannot move one '
                    f'tick per cycle of {config.driver_cycle} s: {names}; raise '
                    f'speed_override')
            tol = np.maximum(tol, ticks)
            settle_tol = ticks.copy()      # what the driver resolves: one tick per joint
        log_length = int(np.ceil(4.0 * config.driver_cycle * config.rate)) + 2
        return {'config': config, 'tol': tol, 'settle_tol': settle_tol, 'vlim': vlim,
                'ticks': ticks, 'min_speed': min_speed, 'dt': 1.0 / config.rate,
                'log_length': log_length}

    def _apply(self, derived):
        """Install what ``_derive`` returned (the config last: ``prepare_demand`` reads it)."""
        self._tol, self._settle_tol = derived['tol'], derived['settle_tol']
        self._vlim, self._dt = derived['vlim'], derived['dt']
        self._ticks, self._min_speed = derived['ticks'], derived['min_speed']
        old = getattr(self, '_travel_log', ())
        self._travel_log = deque(old, maxlen=derived['log_length'])
        self.config = derived['config']

    def check_config(self, config: ControllerConfig) -> None:
        """Raise ``InvalidInputError`` saying why ``config`` cannot drive this arm."""
        self._derive(config)

    def reconfigure(self, config: ControllerConfig) -> bool:
        """
        Use ``config`` from now on, or from the end of the running motion; return True if now.

        Idle (or waiting, or in fault) it applies at once: tolerances, velocity limits, the
        control period, the driver's ticks. While executing, settling or stopping it is kept
        pending (``pending_parameters`` in the status) and applied on the first tick after the
        motion ends, so a motion runs with one config from start to end; a later call replaces
        a pending config. Raises ``InvalidInputError`` (nothing changed) when it does not fit.
        """
        derived = self._derive(config)
        self._changed = True
        if self._state in sm.MOVING_STATES:
            self._pending_config = derived
            return False
        self._pending_config = None
        self._apply(derived)
        return True

    @property
    def pending_config(self) -> Optional[ControllerConfig]:
        """Return the config waiting for the running motion to end (None when none)."""
        return None if self._pending_config is None else self._pending_config['config']

    @property
    def goal_tolerance(self) -> np.ndarray:
        """Return the goal tolerance (n,) [rad] in use (at least one tick in fraction_of_max)."""
        return self._tol.copy()

    # --- inputs -------------------------------------------------------------------------------

    @property
    def state(self) -> str:
        """Return the current state name (``state_machine.STATES``)."""
        return self._state

    @property
    def motion_id(self) -> int:
        """Return the id of the latest accepted demand (0 before any)."""
        return self._motion_id

    @property
    def plan(self) -> Optional[MotionPlan]:
        """Return the running ``MotionPlan`` (None when none)."""
        return self._plan

    def on_joint_states(self, now: float, q: Sequence[float],
                        qd: Optional[Sequence[float]] = None) -> None:
        """Take valid measured positions (n,) [rad] received at ``now`` [s]."""
        q = self.arm.check_q(q, 'joint_states position')
        self._q = q
        # Measured velocity, when the states carry one: arrival also asks where the arm is going.
        self._qd_measured = (np.zeros_like(q) if qd is None
                             else np.nan_to_num(np.asarray(qd, dtype=float), nan=0.0))
        self._t_states = now
        self._bad_states = None
        self._n_states += 1

    def on_invalid_states(self, now: float, reason: str) -> None:
        """Note joint states rejected at ``now`` [s] (missing joints, non-finite): fault."""
        self._bad_states = str(reason)

    def on_demands(self, now: float, waypoints: np.ndarray, demand_id: str = '') -> int:
        """
        Accept waypoints (N, n) [rad] at ``now`` [s] and return the new motion id.

        Raises ``InvalidInputError`` (the running motion untouched, the refusal kept in the
        status until the next accepted demand) when the demand is empty, has the wrong shape,
        non-finite values or values outside the joint limits, or when the controller cannot
        take a demand now (no joint states, fault, stopping). The same as
        ``commit_demand(prepare_demand(now, waypoints, snapshot()))``, in one thread.
        """
        try:
            return self.commit_demand(self.prepare_demand(now, waypoints, self.snapshot(),
                                                          demand_id))
        except InvalidInputError as err:
            self.reject(now, str(err), demand_id)
            raise

    def snapshot(self) -> Snapshot:
        """Return the ``Snapshot`` a demand is planned from (call it under the node's lock)."""
        state, ref = self._state, self._ref          # each read once
        moving = state != sm.IDLE and ref is not None
        return Snapshot(state, ref if moving else (self._q, None), moving, self._motion_id)

    def prepare_demand(self, now: float, waypoints: np.ndarray,
                       snapshot: Optional[Snapshot] = None,
                       demand_id: str = '') -> PendingDemand:
        """
        Check a demand and plan it from ``snapshot``; return a ``PendingDemand``.

        Reads nothing of the controller but ``snapshot`` (and the constant arm and config), so
        a node calls it without holding its lock while the ticks go on (planning the continuous
        law takes tens of milliseconds), with a snapshot taken under the lock, then
        ``commit_demand`` under the lock. Without ``snapshot`` it takes one itself (the caller
        then holds the lock). Raises as ``on_demands``.
        """
        config = self.config       # read once, before the limits it comes with (_apply)
        vlim = self._vlim
        snapshot = self.snapshot() if snapshot is None else snapshot
        Q = self.check_demand(waypoints)
        self._check_accepts(snapshot.state)
        q_start, qd_start = snapshot.start
        if q_start is None:
            raise InvalidInputError(f'cannot take a demand while {snapshot.state}: no joint '
                                    f'states yet')
        plan = plan_motion(config.law, q_start, Q, vlim, qd_start)
        guard = self.collision_guard
        if guard is not None:
            guard(plan)         # raises InvalidInputError: the motion collides
        return PendingDemand(now, Q, plan, snapshot.moving, snapshot.motion_id, demand_id,
                             config)

    def check_demand(self, waypoints: np.ndarray) -> np.ndarray:
        """Return the demand as (N, n) [rad] inside the limits, or raise ``InvalidInputError``."""
        n = self.arm.n_joints
        Q = np.asarray(waypoints, dtype=float)
        if Q.size == 0:
            raise InvalidInputError('demand is empty')
        if Q.ndim == 1:
            if Q.size % n:
                raise InvalidInputError(f'demand length {Q.size} is not a multiple of {n}')
            Q = Q.reshape(-1, n)
        if Q.ndim != 2 or Q.shape[1] != n:
            raise InvalidInputError(f'demand must have shape (N, {n}), got {Q.shape}')
        if not np.all(np.isfinite(Q)):
            raise InvalidInputError('demand has non-finite values')
        bad = [f'waypoint {k}: ' + ', '.join(self.arm.limit_violations(row, tol=1e-6))
               for k, row in enumerate(Q) if not self.arm.within_limits(row, tol=1e-6)]
        if bad:
            raise InvalidInputError('demand outside joint limits: ' + '; '.join(bad))
        return np.clip(Q, self.arm.lower, self.arm.upper)   # float32 rounding at a limit

    def commit_demand(self, pending: PendingDemand) -> int:
        """
        Start a prepared demand (time counts from when it was prepared); return the motion id.

        Call it under the node's lock. When the controller moved on since the snapshot (the
        motion ended, another started: ``is_current`` is False) the demand is planned again
        from a new snapshot; raises when it cannot take a demand any more.
        """
        self._check_accepts(self._state)
        plan = pending.plan
        if not self.is_current(pending):
            snapshot = self.snapshot()
            plan = plan_motion(self.config.law, snapshot.start[0], pending.waypoints,
                               self._vlim, snapshot.start[1])
        self._plan, self._t_plan = plan, pending.now
        self._motion_id += 1
        self._waypoints_total, self._waypoint = len(pending.waypoints), 0
        self._result = {}
        self._rejection = {}
        self._arrived_at = None
        self._set(sm.DEMAND, 'OK', f'motion {self._motion_id}: {len(pending.waypoints)} '
                                   f'waypoint(s), {self.config.law.profile}, '
                                   f'{plan.duration:.2f} s')
        return self._motion_id

    def is_current(self, pending: PendingDemand) -> bool:
        """
        Return whether ``pending`` still fits the controller (``commit_demand`` would not re-plan).

        It does not once the motion it was planned from ended or another one started; a node
        then prepares the demand again without its lock rather than let the commit plan under
        it (the ticks would wait for the planning).
        """
        snapshot = self.snapshot()
        return (snapshot.moving == pending.moving and snapshot.motion_id == pending.motion_id
                and self._state in sm.ACCEPTS_DEMANDS and pending.config is self.config)

    def reject(self, now: float, reason: str, demand_id: str = '') -> None:
        """Note a refused demand: reason, time [s] and id stay in the status until one is taken."""
        self._rejection = {'rejected': str(reason), 'rejected_time': f'{now:.3f}',
                           'rejected_goal_id': str(demand_id)}
        self._changed = True

    def _check_accepts(self, state):
        if state not in sm.ACCEPTS_DEMANDS:
            raise InvalidInputError(f'cannot take a demand while {state}: {self._message}')

    def request_stop(self, now: float) -> tuple[bool, str]:
        """Decelerate to rest and hold; return ``(True, message)`` or why nothing moved."""
        if self._state not in (sm.EXECUTING, sm.SETTLING):
            return True, f'not moving ({self._state}); command is zero'
        q_ref, qd_ref = self._ref if self._ref is not None else (self._q, self._qd_cmd)
        self._plan, self._t_plan = plan_stop(q_ref, qd_ref, self.config.law.a_max), now
        self._result = {'result': 'stopped', 'reason': 'stop requested'}
        self._set(sm.STOP, 'OK', f'stopping motion {self._motion_id} on request')
        return True, f'stopping within {self._plan.duration:.2f} s'

    def reset(self, now: float) -> None:
        """Leave fault: wait for fresh joint states again."""
        if self._state == sm.FAULT:
            self._q = None
            self._set(sm.RESET, 'WARN', 'reset: waiting for /joint_states')

    # --- the tick -----------------------------------------------------------------------------

    def tick(self, now: float) -> TickOutput:
        """Return the ``TickOutput`` at ``now`` [s]: check the states, run the law."""
        self._check_states(now)
        state = self._state
        qd = None
        if state == sm.EXECUTING:
            qd = self._tick_executing(now)
        elif state == sm.SETTLING:
            qd = self._tick_settling(now)
        elif state == sm.STOPPING:
            qd = self._tick_stopping(now)
        if qd is None or self._state not in sm.MOVING_STATES:
            qd = np.zeros(self.arm.n_joints)
            self._ref = None
        else:
            if self._ticks is not None and self._state in (sm.EXECUTING, sm.SETTLING):
                qd = self._whole_ticks(now, qd)
            qd = guard_position_limits(qd, self._q, self.arm.lower, self.arm.upper, self._dt)
        self._n_states_seen = self._n_states
        if self._ticks is not None:
            self._travel_log.append((now, self._travel.copy()))
            self._travel = self._travel + qd * self._dt
        self._qd_cmd = qd
        jog = to_jog_units(qd, self.arm.velocity_limits, self.config.jog_units,
                           self.config.speed_override)
        if self._pending_config is not None and self._state not in sm.MOVING_STATES:
            self._apply(self._pending_config)      # the motion ended: the new config now
            self._pending_config = None
            self._changed = True
        changed, self._changed = self._changed, False
        return TickOutput(qd, jog, self._state, changed)

    def _whole_ticks(self, now, qd):
        """
        Return the command with the dead zone of a whole-tick driver compensated (pulses).

        A pulse starts on the first tick after a fresh reading, lasts one driver cycle (plus
        half a control period, so it surely spans one cycle boundary and not two) and moves its
        joint one tick; the next may start only on a reading that shows it.
        """
        pulsing = now < self._pulse_until
        fresh = self._n_states > self._n_states_seen
        may_start = fresh & (self._n_states >= self._pulse_after)
        qd, dead = dead_zone_command(qd, self._error, self._ticks, self._min_speed,
                                     pulsing | may_start)
        started = dead & ~pulsing & may_start & (qd != 0.0)
        self._pulse_until[started] = now + self.config.driver_cycle + 0.5 * self._dt
        self._pulse_after[started] = self._n_states + 2
        law = ~dead & (qd != 0.0)          # moved by the law: in flight for up to two cycles
        self._pulse_until[law] = -np.inf
        self._pulse_after[law] = self._n_states + 3
        return qd

    def _in_flight(self):
        """
        Return the motion (n,) [rad] commanded that the latest reading cannot show yet.

        The driver applies the command it holds at its cycle and the reading of that cycle is
        taken before the move, so what was commanded from one cycle before that cycle may still
        be on its way; counting from two cycles before the reading came also covers delays of
        up to a cycle (erring towards 'in flight' only delays the arrival).
        """
        since = self._t_states - 2.0 * self.config.driver_cycle
        start = self._travel
        for t, travel in reversed(self._travel_log):
            start = travel
            if t <= since:
                break
        return self._travel - start

    def _check_states(self, now):
        if self._q is None:
            if self._bad_states is not None:
                message = f'waiting for valid /joint_states: {self._bad_states}'
                if message != self._message:
                    self._message, self._changed = message, True
            return
        if self._bad_states is not None:
            reason = f'invalid /joint_states: {self._bad_states}'
        elif now - self._t_states > self.config.state_timeout:
            reason = (f'/joint_states stale: last valid {now - self._t_states:.3f} s ago '
                      f'(timeout {self.config.state_timeout} s)')
        else:
            reason = None
        if reason is not None:
            if self._state != sm.FAULT and sm.accepts(self._state, sm.STATES_INVALID):
                if self._state in sm.MOVING_STATES:
                    self._result = {'result': 'fault', 'reason': reason}
                self._plan = None
                self._t_fault = now
                self._set(sm.STATES_INVALID, 'ERROR', reason)
            return
        if self._state == sm.WAITING_FOR_STATES:
            self._set(sm.STATES_VALID, 'OK', 'joint states received; idle')
        elif self._state == sm.FAULT and self._t_states > self._t_fault:
            self._set(sm.STATES_VALID, 'OK', 'valid joint states again; idle')

    def _tick_executing(self, now):
        t = now - self._t_plan
        q_ref, qd_ref = self._plan.sample(t)
        self._ref = (q_ref, qd_ref)
        self._waypoint = self._plan.waypoints_reached(t)
        self._error = q_ref - self._q
        worst = float(np.max(np.abs(self._error)))
        if worst > self.config.path_tolerance:
            self._plan, self._t_plan = plan_stop(q_ref, qd_ref, self.config.law.a_max), now
            reason = (f'tracking error {worst:.3f} rad above path tolerance '
                      f'{self.config.path_tolerance} rad')
            self._result = {'result': 'aborted', 'reason': reason}
            self._set(sm.PATH_ERROR, 'WARN', f'aborting motion {self._motion_id}: {reason}')
            return self._tick_stopping(now)
        if t >= self._plan.duration:
            self._t_settle = now
            self._set(sm.REFERENCE_DONE, 'OK', f'motion {self._motion_id}: settling')
            return self._tick_settling(now)
        return closed_loop_command(q_ref, qd_ref, self._q, self.config.position_gain,
                                   self._vlim)

    def _tick_settling(self, now):
        """
        Converge on the goal: 'arrived' inside the goal tolerance, then on to the fine one.

        The result 'arrived' is reported when every joint is inside ``goal_tolerance`` (as it
        always was); the state stays settling, with a zero reference velocity, until every
        joint is inside the settle tolerance or ``settle_time`` has passed since the arrival,
        then the controller goes idle and holds with a zero command.
        """
        goal = self._plan.q_goal
        self._ref = (goal, np.zeros_like(goal))
        self._waypoint = self._waypoints_total
        self._error = goal - self._q
        worst = float(np.max(np.abs(self._error)))
        if self._arrived_at is None:
            if np.all(self._within(self._tol)):
                self._arrived_at = now
                self._result = {'result': 'arrived', 'final_joint_error': f'{worst:.6f}'}
                self._message = (f'motion {self._motion_id} arrived (max joint error '
                                 f'{worst:.4f} rad); settling')
                self._changed = True
            elif now - self._t_settle > self.config.settle_timeout:
                reason = (f'not within goal tolerance after {self.config.settle_timeout} s '
                          f'(max joint error {worst:.4f} rad)')
                self._result = {'result': 'aborted', 'reason': reason,
                                'final_joint_error': f'{worst:.6f}'}
                self._set(sm.SETTLE_TIMEOUT, 'WARN', f'motion {self._motion_id}: {reason}')
                return None
        if self._arrived_at is not None:
            fine = np.all(self._within(self._settle_tol))
            if fine or now - self._arrived_at >= self.config.settle_time:
                if self._ticks is not None and np.any(self._in_flight() != 0.0):
                    # Settle time over: command zero until what is in flight has landed, so
                    # the arm is still once idle (the driver lags up to two cycles).
                    return np.zeros_like(goal)
                self._result = dict(self._result, settled_joint_error=f'{worst:.6f}')
                how = 'settled' if fine else f'settle time {self.config.settle_time} s over'
                self._set(sm.SETTLED, 'OK', f'motion {self._motion_id} arrived; {how} '
                                            f'(max joint error {worst:.6f} rad); holding')
                return None
            return self._fine_command(goal)
        return closed_loop_command(goal, np.zeros_like(goal), self._q,
                                   self.config.position_gain, self._vlim)

    def _within(self, tol):
        """Return which joints are within ``tol`` (n,) of the goal, counting what still moves."""
        within = np.abs(self._error) <= tol
        if self._ticks is not None:
            within &= np.abs(self._error - self._in_flight()) <= tol
        else:
            # Not arrived while still moving: where the arm will be two ticks from now must be
            # within tolerance too (a law that ends at full speed, such as the synchronised one,
            # would otherwise declare arrival and coast one tick past the goal).
            within &= np.abs(self._error - 2.0 * self._dt * self._qd_measured) <= tol
        return within

    def _fine_command(self, goal):
        """
        Return the command that closes the last of the error after arrival (n,) [rad/s].

        The gain is at least ``FINE_GAIN_PER_TICK`` per control period (rad_per_s; the
        readings are fresh) or per driver cycle on the error minus what is still in flight
        (fraction_of_max: the readings lag up to two cycles), so the error falls from the goal
        tolerance to the settle tolerance in a fraction of a second without overshoot.
        """
        if self._ticks is None:
            gain = max(self.config.position_gain, FINE_GAIN_PER_TICK / self._dt)
            q = self._q
        else:
            gain = max(self.config.position_gain,
                       FINE_GAIN_PER_CYCLE / self.config.driver_cycle)
            q = self._q + self._in_flight()
        return closed_loop_command(goal, np.zeros_like(goal), q, gain, self._vlim)

    def _tick_stopping(self, now):
        t = now - self._t_plan
        q_ref, qd_ref = self._plan.sample(t)
        self._ref = (q_ref, qd_ref)
        self._error = q_ref - self._q
        if t >= self._plan.duration:
            self._plan = None
            result = self._result.get('result', 'stopped')
            self._set(sm.AT_REST, 'OK' if result == 'stopped' else 'WARN',
                      f'motion {self._motion_id} {result}: at rest, holding')
            return None
        return qd_ref.copy()

    def _set(self, event, level, message):
        self._state = sm.step(self._state, event)
        self._level, self._message = level, message
        self._changed = True

    # --- status -------------------------------------------------------------------------------

    def status(self) -> Status:
        """Return the ``Status`` to publish now (state, level, reason, figures)."""
        moving = self._state in sm.MOVING_STATES
        error = self._error if moving else np.zeros(self.arm.n_joints)
        values = {
            'state': self._state,
            'motion_id': self._motion_id,
            'waypoint': self._waypoint,
            'waypoints': self._waypoints_total,
            'tracking_error': f'{float(np.linalg.norm(error)):.6f}',
            'max_joint_error': f'{float(np.max(np.abs(error))):.6f}',
            'profile': self.config.law.profile,
            'jog_units': self.config.jog_units,
            'rate': f'{self.config.rate:g}',
            'goal_tolerance': ' '.join(f'{t:.6f}' for t in self._tol),
        }
        if self._pending_config is not None:
            pending = self._pending_config['config']
            values['pending_parameters'] = ', '.join(
                f'{name} {value}' for name, value in config_changes(self.config, pending))
        values.update(self._result)
        values.update(self._rejection)
        return Status(self._state, self._level, self._message, values)
