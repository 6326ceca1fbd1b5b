"""
The simulated arm: MuJoCo physics behind the same command interface as the real drives.

ROS-free and clock-free: the caller steps the physics, passes the receive time of every command
(on the simulator's own clock, ``Simulator.time``) and paces against wall time with
``pacing.steps_due``. Two command modes:

``'rad_per_s'`` (ROS standard, MoveIt Servo with unitless scaling off)
    A command gives joint velocities [rad/s] by joint name; joints it does not name get zero.
    Speeds above a joint's limit are clamped to it (the command reports a warning). A command
    older than ``command_timeout`` (by receive time) halts the joints: the last physics step
    that uses it starts at most ``command_timeout`` after its receipt, and from then on the
    servos are asked for zero (the stiff servo brakes within a few milliseconds). Positions are
    never driven past the joint limits: near a limit a joint glides onto it. ``state()``
    reads the physics: q, qd, motor torque.

``'vendor_driver'`` (the Mover6's own cpr_robot driver)
    A command gives fractions of each joint's maximum speed (clamped to [-1, 1]); joints it does
    not name keep their last fraction, and the last command is held with no timeout (send zeros
    to stop). Every ``vendor_cycle`` (50 ms, 20 Hz) the driver reads the encoders (positions in
    whole ticks; velocity = position difference over the cycle; effort 0, as the driver
    reports) and moves each joint's target by ``trunc(fraction * max_speed * speed_override *
    cycle / tick)`` whole encoder ticks, clamped to the joint limits. The joint servo follows the
    target in a straight line over the next cycle. Steps below one tick per cycle are lost, so
    J5 and J6 (2 pi / 1024 rad per tick) stand still under about 7 deg/s.

Contacts: the model's geoms are the collision checker's (``mover6_control.collision``). They
exert no force, but after every physics step MuJoCo's collision detection runs on them
(``mj_collision``, the physics' contact flag lifted for that call only): ``contacts()`` names
the shapes touching now, ``contact_steps`` counts the steps with any contact and
``first_contact`` keeps the first (time, the deepest pair's shapes, its depth) since the last
reset.

Encoder ticks of the Mover6: the vendor driver (cpr_robot, CPRMover6.cpp) sets gear ratios 528.2,
528.2, 528.2, 499.1, 1, 1 and 1440, 1440, 1440, 1440, 1024, 1024 encoder ticks per motor turn,
so one tick is 2 pi / (gear * ticks) of the joint: 8.26e-6 rad for J1 to J3, 8.74e-6 rad for J4
and 6.14e-3 rad (0.352 deg) for J5 and J6. The J5/J6 figures are consistent with the real arm,
whose J5 and J6 stand still under about 7 deg/s (0.352 deg / 0.05 s = 7.0 deg/s).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import math

from mover6_control.errors import InvalidInputError, NonFiniteError
from mover6_control.kinematics.arm import ArmModel, MOVER6_DRIVER_CYCLE, MOVER6_TICK_SIZE
from mover6_control.parameters import SIM_BRIDGE, SIM_MODES   # the defaults, the modes
from mover6_control.values import JogRequest
import mujoco
import numpy as np
from sim_bridge.model import build_model, joint_dof_addresses, joint_qpos_addresses, ModelOptions

_EPS = 1e-9
_LIMIT_APPROACH = 5.0    # physics steps over which a joint may close its gap to a limit
STILL_SPEED = 1e-4       # [rad/s] a joint slower than this is still (the arm rests: at_rest)


@dataclass(frozen=True)
class SimConfig:
    """How the simulated arm behaves; units in brackets."""

    mode: str = SIM_BRIDGE['mode'].default
    command_timeout: float = SIM_BRIDGE['command_timeout'].default   # [s], 'rad_per_s' only
    speed_override: float = SIM_BRIDGE['speed_override'].default   # 'vendor_driver', in (0, 1]
    vendor_cycle: float = MOVER6_DRIVER_CYCLE   # [s], 'vendor_driver' only
    tick_size: tuple = MOVER6_TICK_SIZE         # (n,) [rad], 'vendor_driver' only
    tracking_gain: float = 50.0                 # [1/s] vendor target tracking
    model: ModelOptions = field(default_factory=ModelOptions)

    def __post_init__(self):
        """Check the mode and every number."""
        if self.mode not in SIM_MODES:
            raise InvalidInputError(f'unknown mode "{self.mode}", expected one of {SIM_MODES}')
        if not (math.isfinite(self.command_timeout) and self.command_timeout > 0.0):
            raise InvalidInputError(
                f'command_timeout must be positive, got {self.command_timeout}')
        if not (math.isfinite(self.speed_override) and 0.0 < self.speed_override <= 1.0):
            raise InvalidInputError(
                f'speed_override must be in (0, 1], got {self.speed_override}')
        if not (math.isfinite(self.vendor_cycle) and self.vendor_cycle > 0.0):
            raise InvalidInputError(f'vendor_cycle must be positive, got {self.vendor_cycle}')
        if self.vendor_cycle < self.model.physics_dt:
            raise InvalidInputError(
                f'vendor_cycle {self.vendor_cycle} s is shorter than physics_dt '
                f'{self.model.physics_dt} s')
        ticks = np.asarray(self.tick_size, dtype=float)
        if ticks.ndim != 1 or not np.all(np.isfinite(ticks)) or np.any(ticks <= 0.0):
            raise InvalidInputError(f'tick_size must be positive values, got {self.tick_size}')
        object.__setattr__(self, 'tick_size', tuple(float(t) for t in ticks))
        if not (math.isfinite(self.tracking_gain) and self.tracking_gain > 0.0):
            raise InvalidInputError(
                f'tracking_gain must be positive, got {self.tracking_gain}')

    @property
    def physics_dt(self) -> float:
        """Return the physics step [s]."""
        return self.model.physics_dt


@dataclass(frozen=True)
class JointReading:
    """What the arm reports at ``time`` [s]: q [rad], qd [rad/s], effort [N m], each (n,)."""

    time: float
    q: np.ndarray
    qd: np.ndarray
    effort: np.ndarray


def _as_slice(indices):
    """Return a slice for consecutive ``indices`` (cheap views), else the index array."""
    indices = np.asarray(indices)
    if np.array_equal(indices, np.arange(indices[0], indices[0] + len(indices))):
        return slice(int(indices[0]), int(indices[0]) + len(indices))
    return indices


class Simulator:
    """
    One simulated arm: MuJoCo model and data, the command state and the mode's drive logic.

    Not thread-safe: a caller that commands from one thread and steps from another holds a lock.
    """

    def __init__(self, arm: ArmModel, config: SimConfig | None = None,
                 home_q: np.ndarray | None = None) -> None:
        """Build the model of ``arm`` and start at rest at ``home_q`` (n,) [rad] (zeros)."""
        self.arm = arm
        self.config = config or SimConfig()
        n = arm.n_joints
        ticks = self.config.tick_size
        if len(ticks) != n:
            if self.config.mode == 'vendor_driver':
                raise InvalidInputError(
                    f'tick_size has {len(ticks)} values for {n} joints: give one per joint')
            ticks = (1e-9,) * n          # rad_per_s mode does not quantise; placeholder
        self.home_q = self._check_q(np.zeros(n) if home_q is None else home_q, 'home_q')
        self.model = build_model(arm, self.config.model)
        self.data = mujoco.MjData(self.model)
        self._qadr = _as_slice(joint_qpos_addresses(self.model, arm.joint_names))
        self._dadr = _as_slice(joint_dof_addresses(self.model, arm.joint_names))
        self._index = {name: i for i, name in enumerate(arm.joint_names)}
        self._ticks = np.array(ticks)
        self._vmax = np.array(arm.velocity_limits)
        self._n = n
        self._zeros = np.zeros(n)
        self._upper, self._lower = np.array(arm.upper), np.array(arm.lower)
        self._upper_list, self._lower_list = self._upper.tolist(), self._lower.tolist()
        self._inv_tau = 1.0 / (_LIMIT_APPROACH * self.config.physics_dt)
        opt = self.config.model
        self._feedforward = (opt.kv + opt.damping) / opt.kv
        contact_off = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self._opt = self.model.opt       # the struct's wrapper, looked up once (every step)
        self._contact_flags = self._opt.disableflags & ~contact_off
        self._vendor = self.config.mode == 'vendor_driver'   # the config is frozen: once
        self._timeout = self.config.command_timeout + _EPS    # stale after this [s]
        self._geom_names = [mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g) or str(g)
                            for g in range(self.model.ngeom)]
        # MuJoCo's warning kinds (name, index), looked up once: the node asks 100 times a second.
        self._warning_kinds = [(name, int(kind))
                               for name, kind in mujoco.mjtWarning.__members__.items()
                               if int(kind) < len(self.data.warning)]
        self.step_count = 0
        self.command_count = 0       # commands accepted since construction
        self.applied_count = 0       # the last command_count that a physics step used
        self._reset_state(self.home_q)

    # --- state ---------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Return the simulated time [s]; monotonic, also across resets."""
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """Return the joint positions (n,) [rad] of the physics."""
        return self.data.qpos[self._qadr].copy()

    @property
    def qd(self) -> np.ndarray:
        """Return the joint velocities (n,) [rad/s] of the physics."""
        return self.data.qvel[self._dadr].copy()

    @property
    def effort(self) -> np.ndarray:
        """Return the motor torques (n,) [N m], gravity load included."""
        return self.data.qfrc_actuator[self._dadr].copy()

    @property
    def ctrl(self) -> np.ndarray:
        """Return the velocity (n,) [rad/s] the joint servos were last asked for."""
        return np.array(self._demand, dtype=float)

    @property
    def held_command(self) -> np.ndarray:
        """Return the held command (n,): [rad/s] or fractions, by mode."""
        return self._cmd.copy()

    def is_stale(self) -> bool:
        """Return True when no command is active ('rad_per_s': none yet or timed out)."""
        if self._vendor:
            return False
        return self._cmd_time is None or self.data.time - self._cmd_time > self._timeout

    def at_rest(self, speed: float = STILL_SPEED) -> bool:
        """
        Return True when no command moves the arm and every joint is slower than ``speed``.

        'rad_per_s' mode: the held command is zero or stale (halted), and every joint's velocity
        is under ``speed`` [rad/s]. 'vendor_driver' mode: never (the driver's cycle sets its pace).
        """
        if self._vendor:
            return False
        if not self.is_stale() and any(self._cmd_reach):
            return False
        return all(abs(v) < speed for v in self.data.qvel[self._dadr].tolist())

    def warnings(self) -> dict[str, int]:
        """
        Return MuJoCo's warnings so far as {name: count}, e.g. {'mjWARN_BADQACC': 1}.

        A bad-acceleration warning means the physics blew up and MuJoCo reset its state: the
        node reports it rather than let the arm jump silently.
        """
        out = {}
        if not self.data.warning.number.any():     # none: the common case, one call
            return out
        for name, i in self._warning_kinds:
            number = self.data.warning[i].number
            if number > 0:
                out[name] = int(number)
        return out

    def state(self) -> JointReading:
        """Return the ``JointReading`` the arm reports now (the driver's view in vendor mode)."""
        if self._vendor:
            return JointReading(self._read_time, self._read_q.copy(), self._read_qd.copy(),
                                np.zeros(self.arm.n_joints))
        return JointReading(self.time, self.q, self.qd, self.effort)

    # --- commands ------------------------------------------------------------------------

    def set_command(self, names: Sequence[str], velocities: Sequence[float],
                    receive_time: float) -> list[str]:
        """
        Take a velocity command by joint name, received at ``receive_time`` [s] (sim clock).

        For raw input (a script, the CAN arm's set-points): checked once as a
        ``values.JogRequest`` (raises ``InvalidInputError`` with its code and changes nothing on
        no names, repeated names, mismatched lengths or non-finite values), then ``take_jog``.
        """
        if not math.isfinite(receive_time):
            raise NonFiniteError(f'receive_time must be finite, got {receive_time}')
        return self.take_jog(JogRequest(names, np.asarray(velocities).reshape(-1).tolist()),
                             receive_time)

    def take_jog(self, jog: JogRequest, receive_time: float) -> list[str]:
        """
        Take a checked jog, received at ``receive_time`` [s] (sim clock): nothing checked again.

        ``jog``'s velocities are [rad/s] in 'rad_per_s' mode and fractions of each joint's
        maximum speed in 'vendor_driver' mode. Raises ``InvalidInputError`` (and changes
        nothing) for a joint this arm does not have (code ``unknown_joint``). Returns a list of
        warnings (str) about values that were clamped.
        """
        indices = jog.indices(self.arm.joint_names)
        vendor = self._vendor
        cmd = self._cmd.copy() if vendor else np.zeros(self.arm.n_joints)
        warnings = []
        for name, i, value in zip(jog.names, indices, jog.velocities):
            limit = 1.0 if vendor else self._vmax[i]
            if abs(value) > limit:
                # A command at the limit but for rounding (the controller scales to the same
                # limit) is clamped without a warning.
                if abs(value) > limit * (1.0 + 1e-6):
                    unit = 'of max speed' if vendor else 'rad/s'
                    warnings.append(f'{name}: {value:.4g} clamped to '
                                    f'{math.copysign(limit, value):.4g} {unit}')
                value = math.copysign(limit, value)
            cmd[i] = value
        self._set_held(cmd)
        self._cmd_time = float(receive_time)
        self.command_count += 1
        return warnings

    def refresh_command(self, receive_time: float) -> bool:
        """
        Take the held command again, received at ``receive_time`` [s] (sim clock).

        What ``set_command`` with the same names and velocities does, without redoing it: the
        command's timeout restarts at ``receive_time``. Returns False and changes nothing in
        'vendor_driver' mode, without a command, when ``receive_time`` is not finite or before
        the last command, or when the held command is stale by then (it halted the joints: the
        caller sets the command anew).
        """
        last = self._cmd_time
        if (self._vendor or last is None
                or not math.isfinite(receive_time) or receive_time < last
                or receive_time - last > self._timeout):
            return False
        self._cmd_time = float(receive_time)
        self.command_count += 1
        return True

    def _set_held(self, cmd):
        """Hold ``cmd`` (n,) and what each step needs of it: its reach over the limit guard."""
        self._cmd = cmd
        self._cmd_reach = (cmd / self._inv_tau).tolist()

    # --- stepping ------------------------------------------------------------------------

    def step(self, n_steps: int = 1) -> None:
        """Advance the physics by ``n_steps`` steps of ``physics_dt``."""
        control = self._vendor_control if self._vendor else self._servo_control
        model, data, detect = self.model, self.data, self._detect_contacts
        for _ in range(int(n_steps)):
            control()
            mujoco.mj_step(model, data)
            self.step_count += 1
            detect()

    def _detect_contacts(self):
        """Run MuJoCo's collision detection on the present state; note any contact."""
        model, data, opt = self.model, self.data, self._opt
        flags = opt.disableflags
        opt.disableflags = self._contact_flags
        try:
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
        finally:
            opt.disableflags = flags
        if data.ncon:
            self.contact_steps += 1
            if self.first_contact is None:
                dist = data.contact.dist[:data.ncon]
                deepest = int(np.argmin(dist))
                self.first_contact = (self.time, self.contacts()[deepest], float(-dist[deepest]))

    def contacts(self) -> list[tuple[str, str]]:
        """Return the pairs of geom names in contact after the last step (or reset)."""
        if not self.data.ncon:
            return []
        c = self.data.contact
        return [(self._geom_names[int(a)], self._geom_names[int(b)])
                for a, b in zip(c.geom1[:self.data.ncon], c.geom2[:self.data.ncon])]

    def run_for(self, duration: float) -> None:
        """Advance the physics by ``duration`` [s] (rounded to whole steps)."""
        self.step(int(round(duration / self.config.physics_dt)))

    def _servo_control(self):
        """Set the servo velocities for one 'rad_per_s' step."""
        if self.is_stale():
            self._set_servo(self._zeros)     # zero is always inside the limits
            return
        self.applied_count = self.command_count
        # Fast path (plain floats, no small-array numpy calls): is any joint within reach of a
        # limit in the direction it is commanded? Only then apply the guard.
        q = self.data.qpos[self._qadr].tolist()
        for qi, reach, lo, hi in zip(q, self._cmd_reach, self._lower_list, self._upper_list):
            if qi + reach > hi or qi + reach < lo:
                self._set_servo(self._limit_guard(self._cmd))
                return
        self._set_servo(self._cmd)

    def _set_servo(self, v):
        """
        Ask the joint servos for velocity ``v`` (n,) [rad/s].

        The demand is scaled by (kv + damping) / kv, the drive's feed-forward of the joint's
        viscous damping, so that the steady velocity equals ``v`` exactly. The same array as
        the step before (the held command, or zero while stale) is in ``data.ctrl`` already:
        only this method writes it, and a reset gives ``_demand`` a new array.
        """
        if v is self._demand:
            return
        self._demand = v
        self.data.ctrl[:self._n] = v * self._feedforward

    def _limit_guard(self, v):
        """
        Return ``v`` [rad/s] reduced so that no joint runs past its limit.

        Within reach of a limit a joint may close at most the gap over ``_LIMIT_APPROACH``
        physics steps, so it glides onto the limit (exponentially, 10 ms at a 2 ms step) instead
        of overshooting it by the servo's lag; a joint beyond a limit may only move back.
        """
        q = self.data.qpos[self._qadr]
        hi = np.maximum((self._upper - q) * self._inv_tau, 0.0)
        lo = np.minimum((self._lower - q) * self._inv_tau, 0.0)
        return np.minimum(np.maximum(v, lo), hi)

    def _vendor_control(self):
        """Run the driver's 20 Hz cycle when due, then set the servo to follow the target."""
        t = float(self.data.time)
        if t >= self._next_cycle - _EPS:
            self._vendor_cycle()
        ramp = (t - self._cycle_start) / self.config.vendor_cycle
        if ramp < 1.0:
            ref = self._prev_target + self._ramp_delta * ramp
            v = self._v_ff + self.config.tracking_gain * (ref - self.data.qpos[self._qadr])
        else:
            ref = self._prev_target + self._ramp_delta
            v = self.config.tracking_gain * (ref - self.data.qpos[self._qadr])
        self._set_servo(np.minimum(np.maximum(v, -self._vmax), self._vmax))

    def _vendor_cycle(self):
        """One cycle of the vendor driver: read encoders, then move the targets in ticks."""
        cfg = self.config
        now = self.time
        q_read = np.round(self.q / self._ticks) * self._ticks
        if now > self._read_time:
            self._read_qd = (q_read - self._read_q) / (now - self._read_time)
        self._read_q, self._read_time = q_read, now
        self._prev_target = self._target_ticks * self._ticks
        step = self._cmd * self._vmax * cfg.speed_override * cfg.vendor_cycle
        ticks = np.trunc(step / self._ticks + np.copysign(_EPS, step))
        lo = np.ceil(self.arm.lower / self._ticks - _EPS)
        hi = np.floor(self.arm.upper / self._ticks + _EPS)
        self._target_ticks = np.clip(self._target_ticks + ticks, lo, hi)
        self._ramp_delta = self._target_ticks * self._ticks - self._prev_target
        self._v_ff = self._ramp_delta / cfg.vendor_cycle
        if np.any(self._cmd != 0.0):
            self.applied_count = self.command_count
        self._cycle_start = now
        self._next_cycle = now + cfg.vendor_cycle

    # --- reset ---------------------------------------------------------------------------

    def reset(self, q: np.ndarray | None = None) -> None:
        """
        Put the arm at rest at ``q`` (n,) [rad] (default ``home_q``) and drop every command.

        Sim time keeps running forward (a /clock must not jump back); the drive state (vendor
        targets and cycle phase) starts afresh, so what follows a reset is exactly what follows
        a new simulator at that configuration.
        """
        q = self.home_q if q is None else self._check_q(q, 'q')
        self._reset_state(q)

    def _reset_state(self, q):
        """Reset MuJoCo data and the drive state to rest at ``q``, keeping the time."""
        t = float(self.data.time)
        mujoco.mj_resetData(self.model, self.data)
        self.data.time = t
        self.data.qpos[self._qadr] = q
        mujoco.mj_forward(self.model, self.data)
        self.contact_steps = 0
        self.first_contact = None
        self._detect_contacts()
        n = self.arm.n_joints
        self._set_held(np.zeros(n))
        self._cmd_time = None
        self._demand = np.zeros(n)
        self._target_ticks = np.round(q / self._ticks)
        self._prev_target = self._target_ticks * self._ticks
        self._ramp_delta = np.zeros(n)
        self._v_ff = np.zeros(n)
        self._cycle_start = t
        self._next_cycle = t
        self._read_q = np.round(q / self._ticks) * self._ticks
        self._read_qd = np.zeros(n)
        self._read_time = t

    def _check_q(self, q, name):
        """Return ``q`` as a finite (n,) array inside the joint limits, or raise."""
        q = self.arm.check_q(q, name)
        bad = self.arm.limit_violations(q, tol=1e-6)
        if bad:
            raise InvalidInputError(f'{name} is outside the joint limits: {"; ".join(bad)}')
        return q
