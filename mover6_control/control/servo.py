"""
Jogging, as MoveIt Servo does it: the latest twist or joint-jog command to this tick's rates.

``servo_step`` is one pure function of the arm, the settings (``ServoConfig``), what it kept from
the tick before (``ServoState``), the latest command (``TwistCommand`` or ``JointJogCommand``),
the measured joints and the time [s]; it returns the joint velocities of this tick and why the
motion is slowed or halted (``ServoOutput``). No clock, no I/O: the controller calls it.

A twist (linear [m/s], angular [rad/s] of the flange, in ``base_link`` or in the flange frame
``link6``) becomes joint rates by damped least squares of the geometric Jacobian
(``kinematics.forward.jacobian``) with its linear rows divided by the arm's reach
(``arm_reach``), so that metres and radians weigh alike. A reference pose, integrated from the
commanded twist as far as the arm actually follows it, is held by a small proportional term
(``pose_gain``), so the tool does not drift off the commanded line or orientation.

Safety, in MoveIt Servo's terms, every stop with a reason:

- a command older than ``command_timeout`` decelerates the arm to rest; its age counts from
  its stamp or from its arrival (``received``, the controller's clock), whichever is earlier,
  and a stamp more than ``FUTURE_STAMP_TOLERANCE`` after its arrival is refused, so a stamp
  from the future cannot keep the arm moving;
- joint speeds are limited by one common factor (the direction is kept), the change of speed
  per tick by ``a_max`` (one common factor as well);
- the condition number of the normalised Jacobian (scale-free) above
  ``lower_singularity_threshold`` slows a motion that goes towards a singularity, linearly to
  zero at ``hard_stop_singularity_threshold``, and halts when slowed under
  ``MIN_SINGULARITY_SCALE`` or when its next tick would reach the hard threshold; motion away
  from a singularity is never slowed;
- a joint within ``joint_limit_margin`` of a limit and moving towards it halts the motion;
- ``veto`` (the hook for collision checking): a callable ``veto(q, q_ahead)`` returning a
  reason (str) halts the motion before ``q_ahead``, where it would stop; None lets it go.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import math
from typing import Callable, Optional

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk_and_jacobian
from mover6_control.parameters import CONTROLLER   # the defaults
import numpy as np

FRAMES = ('base_link', 'link6')
# Below this fraction of its speed a motion towards a singularity halts: the linear slow-down
# alone would only creep towards the hard threshold, never reach it, never stop.
MIN_SINGULARITY_SCALE = 0.1
# [rad] joint step used to tell whether a motion goes towards a singularity or away from it.
DIRECTION_STEP = 1e-3
# [s] how far a command's stamp may lie after its arrival by the controller's clock (clocks a
# few milliseconds apart, a sim clock a step ahead); a stamp further in the future is refused.
FUTURE_STAMP_TOLERANCE = 0.05


@dataclass(frozen=True)
class ServoConfig:
    """
    The jogging settings (the controller's ``servo_*`` parameters).

    ``command_timeout`` [s]: a command older than this (``command_age``) stops the arm.
    ``pose_gain`` [1/s]: gain holding the reference line and orientation. ``damping``: damped
    least squares factor on the normalised Jacobian (no unit). ``lower_singularity_threshold``,
    ``hard_stop_singularity_threshold``: condition numbers of the normalised Jacobian where the
    slow-down starts and where the motion halts. ``joint_limit_margin`` [rad]: halt a joint
    moving towards a limit this close. ``a_max`` [rad/s^2]: largest change of any joint's speed.
    ``veto``: ``veto(q, q_ahead) -> Optional[str]``, a reason to halt before ``q_ahead`` (this
    tick's step plus the distance to stop at ``a_max``); the controller plugs its collision check
    (``collision_guard.CollisionGuard.veto``) in here when it is on; None checks nothing.
    """

    command_timeout: float = CONTROLLER['servo_command_timeout'].default
    pose_gain: float = CONTROLLER['servo_pose_gain'].default
    damping: float = CONTROLLER['servo_damping'].default
    lower_singularity_threshold: float = CONTROLLER['servo_lower_singularity_threshold'].default
    hard_stop_singularity_threshold: float = (
        CONTROLLER['servo_hard_stop_singularity_threshold'].default)
    joint_limit_margin: float = CONTROLLER['servo_joint_limit_margin'].default
    a_max: float = 1.0
    veto: Optional[Callable[[np.ndarray, np.ndarray], Optional[str]]] = field(
        default=None, compare=False)

    def __post_init__(self):
        """Check every setting."""
        for name in ('command_timeout', 'lower_singularity_threshold',
                     'hard_stop_singularity_threshold', 'a_max'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise InvalidInputError(f'servo {name} must be positive, got {value}')
        for name in ('pose_gain', 'damping', 'joint_limit_margin'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise InvalidInputError(f'servo {name} must be >= 0, got {value}')
        if self.hard_stop_singularity_threshold <= self.lower_singularity_threshold:
            raise InvalidInputError(
                f'servo hard_stop_singularity_threshold ({self.hard_stop_singularity_threshold})'
                f' must be above lower_singularity_threshold '
                f'({self.lower_singularity_threshold})')
        if self.veto is not None and not callable(self.veto):
            raise InvalidInputError(f'servo veto must be callable, got {self.veto!r}')


@dataclass(frozen=True, eq=False)
class TwistCommand:
    """
    A flange twist: ``linear`` (3,) [m/s] and ``angular`` (3,) [rad/s] in ``frame``.

    ``stamp`` [s] is the sender's time, ``received`` [s] the controller's at arrival (None: the
    stamp); the command's age counts from the earlier of the two (``command_age``).
    """

    stamp: float
    linear: np.ndarray
    angular: np.ndarray
    frame: str = 'base_link'
    received: Optional[float] = None

    def __post_init__(self):
        """Check the values, the stamp and the frame; freeze the arrays."""
        _check_stamp(self.stamp, self.received)
        for name in ('linear', 'angular'):
            arr = np.array(getattr(self, name), dtype=float).reshape(-1)
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise InvalidInputError(f'twist {name} must be 3 finite values, got '
                                        f'{arr.tolist()}')
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if self.frame not in FRAMES:
            raise InvalidInputError(f'twist frame must be one of {FRAMES}, got '
                                    f'"{self.frame}"')


@dataclass(frozen=True, eq=False)
class JointJogCommand:
    """Joint velocities ``velocities`` (n,) [rad/s] in the arm's joint order; times as a twist."""

    stamp: float
    velocities: np.ndarray
    received: Optional[float] = None

    def __post_init__(self):
        """Check the values and the stamp; freeze the array."""
        _check_stamp(self.stamp, self.received)
        arr = np.array(self.velocities, dtype=float).reshape(-1)
        if not arr.size or not np.all(np.isfinite(arr)):
            raise InvalidInputError(f'joint jog velocities must be finite, got {arr.tolist()}')
        arr.setflags(write=False)
        object.__setattr__(self, 'velocities', arr)


def _check_stamp(stamp, received):
    if not np.isfinite(stamp):
        raise InvalidInputError(f'command stamp must be finite, got {stamp}')
    if received is None:
        return
    if not np.isfinite(received):
        raise InvalidInputError(f'command arrival time must be finite, got {received}')
    if stamp - received > FUTURE_STAMP_TOLERANCE:
        raise InvalidInputError(
            f'command stamp {stamp:.3f} s is {stamp - received:.3f} s in the future of its '
            f'arrival at {received:.3f} s (tolerance {FUTURE_STAMP_TOLERANCE:g} s): the clocks '
            'disagree')


def command_age(command, now: float) -> float:
    """Return the age [s] of a command at ``now``: from its stamp or arrival, the earlier."""
    start = command.stamp if command.received is None else min(command.stamp, command.received)
    return now - start


def joint_jog_command(arm: ArmModel, stamp: float, names: list, velocities: list,
                      received: Optional[float] = None) -> JointJogCommand:
    """
    Return a ``JointJogCommand`` from joint ``names`` and their ``velocities`` [rad/s].

    ``stamp`` and ``received`` [s] as ``JointJogCommand``'s.

    Joints not named stay still; an unknown or repeated name, or as many names as values not,
    raises ``InvalidInputError``.
    """
    names, values = list(names), list(velocities)
    if not names:
        raise InvalidInputError('joint jog names no joint')
    if len(names) != len(values):
        raise InvalidInputError(f'joint jog has {len(names)} names but {len(values)} velocities')
    if len(set(names)) != len(names):
        raise InvalidInputError(f'joint jog names repeat: {names}')
    qd = np.zeros(arm.n_joints)
    for name, value in zip(names, values):
        qd[arm.joint_index(name)] = value
    return JointJogCommand(stamp, qd, received)


@dataclass(frozen=True, eq=False)
class ServoState:
    """What one tick keeps for the next: the last command ``qd`` (n,), reference pose, time."""

    qd: np.ndarray
    reference: Optional[np.ndarray] = None     # (4, 4) base -> flange; None: not holding one
    time: Optional[float] = None               # [s] of the tick that made it (None: none yet)


@dataclass(frozen=True, eq=False)
class ServoOutput:
    """
    One tick of jogging.

    ``qd`` (n,) [rad/s] the command; ``state`` for the next tick; ``reason`` why the motion is
    slowed or halted ('' when it runs freely); ``halted`` True when a stop condition holds (the
    arm decelerates to rest); ``stale`` True when the command timed out; ``scale`` the factor
    the singularity slow-down applied; ``condition`` the normalised Jacobian's condition number
    (nan in joint mode).
    """

    qd: np.ndarray
    state: ServoState
    reason: str
    halted: bool
    stale: bool
    scale: float
    condition: float

    @property
    def at_rest(self) -> bool:
        """Return True when the command is zero."""
        return not np.any(self.qd)


def initial_state(arm: ArmModel, qd: Optional[np.ndarray] = None) -> ServoState:
    """Return the state jogging starts from: the current command ``qd`` (rest when None)."""
    qd = np.zeros(arm.n_joints) if qd is None else np.array(qd, dtype=float)
    return ServoState(qd)


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def arm_reach(arm: ArmModel) -> float:
    """Return the arm's reach [m]: the summed link lengths from the second joint to the tip."""
    lengths = [np.linalg.norm(arm.origins[i, :3, 3]) for i in range(1, arm.n_joints)]
    return float(sum(lengths) + np.linalg.norm(arm.tool[:3, 3]))


def pose_and_jacobian(arm: ArmModel, q: np.ndarray,
                      reach: Optional[float] = None) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the flange pose (4, 4) and the normalised Jacobian (6, n) at ``q`` from one FK pass.

    The Jacobian is ``kinematics.forward.jacobian``'s (columns ``[z_i x (p - o_i); z_i]``) with
    its linear rows divided by the reach [m] (``arm_reach`` when None), so it is scale-free.
    """
    T, J = fk_and_jacobian(arm, q)
    J[:3] /= arm_reach(arm) if reach is None else reach
    return T, J


def normalised_jacobian(arm: ArmModel, q: np.ndarray, reach: Optional[float] = None) -> np.ndarray:
    """Return the geometric Jacobian (6, n) with its linear rows divided by the reach [m]."""
    return pose_and_jacobian(arm, q, reach)[1]


def condition(J: np.ndarray) -> float:
    """Return the condition number of ``J`` (inf when singular)."""
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0.0 else float('inf')


def damped_rates(J: np.ndarray, twist: np.ndarray, damping: float) -> np.ndarray:
    """Return ``J^T (J J^T + damping^2 I)^-1 twist``: damped least squares joint rates."""
    A = J @ J.T
    A.flat[::len(A) + 1] += damping ** 2
    return J.T @ np.linalg.solve(A, twist)


def _rotation_vector(R):
    """Return the rotation vector (3,) [rad] of ``R`` (angles under pi)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()    # floats: 3x3 is tiny
    x, y, z = (r21 - r12) / 2.0, (r02 - r20) / 2.0, (r10 - r01) / 2.0
    sin = math.sqrt(x * x + y * y + z * z)
    if sin < 1e-12:
        return np.array([x, y, z])
    f = math.atan2(sin, (r00 + r11 + r22 - 1.0) / 2.0) / sin
    return np.array([x * f, y * f, z * f])


def _rotation_matrix(rotvec):
    """Return the rotation matrix of the rotation vector ``rotvec`` (3,) [rad] (Rodrigues)."""
    x, y, z = rotvec.tolist()                                    # floats: 3x3 is tiny
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < 1e-15:
        return np.eye(3)
    x, y, z = x / angle, y / angle, z / angle
    s, v = math.sin(angle), 1.0 - math.cos(angle)    # I + s K + v K^2, K^2 = k k^T - I
    return np.array([[1.0 - v * (y * y + z * z), v * x * y - s * z, v * x * z + s * y],
                     [v * x * y + s * z, 1.0 - v * (x * x + z * z), v * y * z - s * x],
                     [v * x * z - s * y, v * y * z + s * x, 1.0 - v * (x * x + y * y)]])


def _accelerate(qd_prev, target, a_max, dt):
    """Return the step from ``qd_prev`` towards ``target``, by one factor within ``a_max``."""
    delta = target - qd_prev
    biggest = float(np.max(np.abs(delta)))
    if biggest <= a_max * dt:
        return target.copy()
    return qd_prev + delta * (a_max * dt / biggest)


def _limit_halt(arm, q, qd, margin):
    """Return why ``qd`` drives a joint within ``margin`` of a limit further towards it, or ''."""
    for i, name in enumerate(arm.joint_names):
        if qd[i] > 0.0 and q[i] >= arm.upper[i] - margin:
            return (f'{name} at {q[i]:.3f} rad, within {margin:g} rad of its upper limit '
                    f'{arm.upper[i]:.3f}, moving towards it')
        if qd[i] < 0.0 and q[i] <= arm.lower[i] + margin:
            return (f'{name} at {q[i]:.3f} rad, within {margin:g} rad of its lower limit '
                    f'{arm.lower[i]:.3f}, moving towards it')
    return ''


def _twist_target(arm, config, state, command, q, dt, vlim, reach):
    """
    Return ``(target qd, fraction, reference, twist kept, reason, halted, scale, condition)``.

    The target is the speed-limited damped least squares solution for the commanded twist plus
    the correction towards the reference pose, slowed near a singularity. ``twist kept`` (6,)
    in base is the commanded twist times the speed limit's factor, and ``fraction`` (0 to 1) the
    share of it the singularity slow-down keeps. A twist of any finite size is divided by its
    largest component (when above 1) before anything else, and the speed limit then applies to
    the rates of that unit twist (the solve is linear): the same command as for the twist
    itself, where 1e308 m/s would overflow the solve.
    """
    T, J = pose_and_jacobian(arm, q, reach)
    reference = T.copy() if state.reference is None else state.reference
    R_ref = reference[:3, :3]
    size = max(1.0, float(np.max(np.abs(command.linear))),
               float(np.max(np.abs(command.angular))))
    linear, angular = command.linear / size, command.angular / size
    if command.frame == 'link6':
        linear, angular = R_ref @ linear, R_ref @ angular
    twist = np.concatenate([linear, angular])           # the commanded twist / size
    error = np.concatenate([reference[:3, 3] - T[:3, 3], _rotation_vector(R_ref @ T[:3, :3].T)])
    wanted = twist + (config.pose_gain / size) * error
    wanted[:3] *= 1.0 / reach
    qd, gain = _speed_limited(damped_rates(J, wanted, config.damping), size, vlim)
    twist = twist * gain
    cond = condition(J)
    norm = math.sqrt(float(qd @ qd))         # np.linalg.norm's own formula, without its checks
    lower = config.lower_singularity_threshold
    hard = config.hard_stop_singularity_threshold
    if norm == 0.0 or cond < lower:
        return qd, 1.0, reference, twist, '', False, 1.0, cond
    ahead = condition(normalised_jacobian(arm, q + qd * (DIRECTION_STEP / norm), reach))
    if ahead <= cond:
        return qd, 1.0, reference, twist, '', False, 1.0, cond
    scale = (hard - cond) / (hard - lower)
    if (scale < MIN_SINGULARITY_SCALE
            or condition(normalised_jacobian(arm, q + qd * scale * dt, reach)) >= hard):
        reason = (f'halted before a singularity: condition {cond:.1f} (slows from {lower:g}, '
                  f'hard stop at {hard:g}); move away from it')
        return np.zeros_like(qd), 0.0, reference, twist, reason, True, 0.0, cond
    reason = (f'slowed to {scale:.0%} near a singularity: condition {cond:.1f} (slows from '
              f'{lower:g}, halts at {hard:g})')
    return qd * scale, scale, reference, twist, reason, False, scale, cond


def _speed_limited(rates, size, vlim):
    """
    Return ``(rates * gain, gain)``: ``gain`` is ``size``, or less to keep within ``vlim`` (n,).

    ``rates`` (n,) are a command's joint rates divided by ``size`` (>= 1), so neither they nor
    the result overflow for any finite command; one common factor keeps the direction.
    """
    gain = min(size, float(np.min(vlim / np.maximum(np.abs(rates), 1e-300))))
    return rates * gain, gain


def servo_step(arm: ArmModel, config: ServoConfig, state: ServoState, command, q: np.ndarray,
               now: float, dt: float, vlim: np.ndarray) -> ServoOutput:
    """
    Return this tick's ``ServoOutput`` for ``command`` at ``now`` [s] from measured ``q`` [rad].

    ``command`` is a ``TwistCommand``, a ``JointJogCommand`` or None (no command yet);
    ``dt`` [s] is the tick period and ``vlim`` (n,) [rad/s] the joint speed limits in force.
    The reference pose advances by the time since the tick before (``dt`` on the first), so a
    late or skipped tick does not leave it, and the arm it holds, behind.
    """
    q = arm.check_q(q)
    vlim = np.asarray(vlim, dtype=float)
    if not (np.isfinite(dt) and dt > 0.0):
        raise InvalidInputError(f'dt must be positive, got {dt}')
    reach = arm_reach(arm)
    reference, twist = None, None
    reason, halted, stale, scale, cond = '', False, False, 1.0, float('nan')
    if command is None:
        target, reason, halted, stale = np.zeros(arm.n_joints), 'no command yet', True, True
    elif command_age(command, now) > config.command_timeout:
        target, halted, stale = np.zeros(arm.n_joints), True, True
        reason = (f'commands stale: the latest is {command_age(command, now):.3f} s old '
                  f'(timeout {config.command_timeout:g} s)')
    elif isinstance(command, TwistCommand):
        if not (np.any(command.linear) or np.any(command.angular)):
            target, reason, halted = np.zeros(arm.n_joints), 'zero twist commanded', True
        else:
            target, fraction, reference, twist, reason, halted, scale, cond = _twist_target(
                arm, config, state, command, q, dt, vlim, reach)
    elif isinstance(command, JointJogCommand):
        if command.velocities.shape != (arm.n_joints,):
            raise InvalidInputError(f'joint jog must have {arm.n_joints} velocities, got '
                                    f'{command.velocities.size}')
        size = max(1.0, float(np.max(np.abs(command.velocities))))
        target = _speed_limited(command.velocities / size, size, vlim)[0]
    else:
        raise InvalidInputError(f'unknown servo command {command!r}')
    if not halted:
        why = _limit_halt(arm, q, target, config.joint_limit_margin)
        if not why and config.veto is not None:
            # Ahead by this tick and the distance to stop from the target speed at a_max, so a
            # veto leaves room to decelerate before the vetoed pose.
            ahead = q + target * dt + target * np.abs(target) / (2.0 * config.a_max)
            why = config.veto(q, ahead) or ''
            why = f'vetoed: {why}' if why else ''
        if why:
            target, reason, halted, scale = np.zeros(arm.n_joints), 'halted: ' + why, True, 0.0
    qd = _accelerate(state.qd, target, config.a_max, dt)
    if reference is not None:
        elapsed = dt if state.time is None else min(max(now - state.time, 0.0),
                                                    config.command_timeout)
        size = float(target @ target)
        if halted or not size > 1e-300:   # a vanishing target (denormal twist): no progress
            progress = 0.0
        else:    # the acceleration limit's share of the target reached this tick
            progress = fraction * min(max(float(qd @ target) / size, 0.0), 1.0)
        reference = _advance(reference, twist, progress, elapsed)
    return ServoOutput(qd, ServoState(qd, reference, now), reason, halted, stale, scale, cond)


def _advance(reference, twist, progress, dt):
    """
    Return the reference pose moved by ``progress`` (0 to 1) of the ``twist`` in ``dt``.

    ``twist`` is the commanded twist as the speed limit keeps it, ``progress`` the share of it
    this tick's command makes (after the singularity and acceleration limits, not counting the
    correction), so a slowed or accelerating arm does not fall behind its reference, nor an arm
    ahead of it hold it back.
    """
    out = reference.copy()
    out[:3, 3] += twist[:3] * progress * dt
    if np.any(twist[3:]) and progress > 0.0:
        out[:3, :3] = _rotation_matrix(twist[3:] * progress * dt) @ reference[:3, :3]
    return out
