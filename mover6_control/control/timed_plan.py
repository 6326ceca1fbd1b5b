"""
A motion plan that keeps the timing a goal gives its points: ``time_from_start``, velocities.

What a ``FollowJointTrajectory`` goal (MoveIt's, any trajectory tool's) asks for: each point
reached at its ``time_from_start`` [s], with its velocities (and accelerations) when given. As
joint_trajectory_controller does, the reference is piecewise polynomial through the points, from
the present reference ``(q_start, qd_start)`` at t = 0 (at rest, or the commanded velocity when
the goal replaces a running motion):

- positions, velocities and accelerations given: quintic Hermite per segment;
- positions and velocities: cubic Hermite per segment;
- positions only: a cubic spline through the points, its velocity continuous (C2), clamped to
  ``qd_start`` at the start and to rest at the last point (joint_trajectory_controller
  interpolates linearly there; a velocity-commanded arm cannot follow the velocity jumps).

A first point at ``time_from_start`` 0 is where the goal says the arm is (MoveIt's first point
is the start state): it must lie within ``START_TOLERANCE`` of ``q_start`` and the plan starts
from ``q_start`` (the closed loop absorbs the difference). The times must then increase strictly
and the last point's velocities (when given) be zero: the arm stops there.

The timing is honoured only within the limits: the exact peaks of every joint's speed and
acceleration (piece ends and stationary points, not samples) must stay within the velocity
limits and ``a_max``, and the positions within the joint limits. ``plan_demand`` otherwise plans
the law's time-optimal motion through the same points and says why (``TimingError``'s reason),
so a caller logs it and reports it. Points whose ``time_from_start`` are all zero are untimed:
the law's plan.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

from mover6_control.control.motion_plan import MotionPlan
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.control.status import TIMING_AS_GIVEN
from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_positive
import numpy as np
from scipy.interpolate import CubicSpline, PPoly

# [rad] A first point at time_from_start 0 may lie this far from the start, per joint (the
# default of joint_trajectory_controller's allowed_start_tolerance).
START_TOLERANCE = 0.01
# [rad/s] The last point's velocities count as zero below this.
REST_SPEED = 1e-6
# Relative rounding allowed on the peaks against the limits.
LIMIT_MARGIN = 1e-9


class TimingError(InvalidInputError):
    """The given timing cannot be followed (the reason says why); the law's plan is used."""


@dataclass(frozen=True, eq=False)
class Timing:
    """
    The timing of a demand's points: ``times`` (N,) [s] from the start, non-decreasing, >= 0.

    ``velocities`` (N, n) [rad/s] and ``accelerations`` (N, n) [rad/s^2] of every point, or None
    when the goal gives none (accelerations only with velocities).
    """

    times: np.ndarray
    velocities: Optional[np.ndarray] = None
    accelerations: Optional[np.ndarray] = None

    def __post_init__(self):
        """Check the shapes and that every value is finite and the times non-decreasing."""
        times = np.asarray(self.times, dtype=float)
        if times.ndim != 1 or not times.size:
            raise InvalidInputError(f'times must be (N,), got shape {times.shape}')
        if not np.all(np.isfinite(times)) or np.any(times < 0.0) or np.any(np.diff(times) < 0):
            raise InvalidInputError(f'times must be finite, >= 0 and non-decreasing, got '
                                    f'{times.tolist()}')
        object.__setattr__(self, 'times', times)
        for name in ('velocities', 'accelerations'):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.ndim != 2 or value.shape[0] != times.size or not np.all(np.isfinite(value)):
                raise InvalidInputError(f'{name} must be finite, one row per point '
                                        f'({times.size}), got shape {value.shape}')
            object.__setattr__(self, name, value)
        if self.accelerations is not None and self.velocities is None:
            raise InvalidInputError('accelerations need velocities')

    @property
    def timed(self) -> bool:
        """Return whether any point has a ``time_from_start`` (all zero: untimed)."""
        return bool(self.times[-1] > 0.0)


@dataclass(frozen=True, eq=False)
class TimedSegment:
    """The piecewise polynomial ``spline`` (PPoly, values (n,)) over [0, duration], then held."""

    spline: PPoly
    duration: float
    q1: np.ndarray

    def __post_init__(self):
        """Keep the derivative, evaluated every tick."""
        object.__setattr__(self, '_velocity', self.spline.derivative(1))

    def sample(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` (n,) at ``tau`` [s] into the segment."""
        if tau >= self.duration:
            return self.q1.copy(), np.zeros_like(self.q1)
        return np.asarray(self.spline(tau), dtype=float), np.asarray(self._velocity(tau),
                                                                     dtype=float)

    def positions(self, tau: np.ndarray) -> np.ndarray:
        """Return ``q`` (m, n) at ``tau`` (m,) [s], as ``sample`` each: one spline call."""
        out = np.empty((tau.size, self.q1.size))
        moving = tau < self.duration
        out[moving] = self.spline(tau[moving])
        out[~moving] = self.q1
        return out


def hermite_coefficients(h: np.ndarray, q0, v0, q1, v1, a0=None, a1=None) -> np.ndarray:
    """
    Return PPoly coefficients (6, m, n) of the Hermite pieces of widths ``h`` (m,) [s].

    Each piece goes from ``(q0, v0[, a0])`` to ``(q1, v1[, a1])`` (each (m, n)): quintic when
    accelerations are given, cubic (the two highest coefficients zero) otherwise.
    """
    h = np.asarray(h, dtype=float)[:, None]
    dq = q1 - q0
    c = np.zeros((6,) + dq.shape)
    if a0 is None:
        c[2] = (2.0 * -dq + h * (v0 + v1)) / h ** 3
        c[3] = (3.0 * dq - h * (2.0 * v0 + v1)) / h ** 2
    else:
        c[0] = (12.0 * dq - 6.0 * h * (v0 + v1) - h ** 2 * (a0 - a1)) / (2.0 * h ** 5)
        c[1] = (-30.0 * dq + h * (14.0 * v1 + 16.0 * v0) + h ** 2 * (3.0 * a0 - 2.0 * a1)) / (
            2.0 * h ** 4)
        c[2] = (20.0 * dq - h * (8.0 * v1 + 12.0 * v0) - h ** 2 * (3.0 * a0 - a1)) / (
            2.0 * h ** 3)
        c[3] = a0 / 2.0
    c[4], c[5] = v0, q0
    return c


def peak(spline: PPoly, order: int, joint: int) -> tuple[float, float]:
    """
    Return ``(min, max)`` of the ``order``-th derivative of one joint of ``spline``.

    Exact for a polynomial: the values at both ends of every piece (both one-sided limits) and
    at the stationary points inside.
    """
    column = PPoly(spline.c[:, :, joint], spline.x)
    d = column.derivative(order) if order else column
    h = np.diff(d.x)
    right = np.zeros(d.c.shape[1])
    for coef in d.c:
        right = right * h + coef
    values = [d.c[-1], right]
    roots = d.derivative(1).roots(discontinuity=False, extrapolate=False)
    roots = roots[np.isfinite(roots)]
    if roots.size:
        values.append(d(roots))
    values = np.concatenate(values)
    return float(values.min()), float(values.max())


def timed_spline(q_start: np.ndarray, qd_start: np.ndarray, waypoints: np.ndarray,
                 timing: Timing) -> PPoly:
    """
    Return the reference (PPoly, values (n,)) from ``(q_start, qd_start)`` through the points.

    Raises ``TimingError`` when the timing cannot be followed at all (see the module docstring).
    """
    times, Q = timing.times, waypoints
    V, A = timing.velocities, timing.accelerations
    if times[0] == 0.0:
        off = np.abs(Q[0] - q_start)
        if np.any(off > START_TOLERANCE):
            raise TimingError(f'the first point (time_from_start 0) is {off.max():.4f} rad from '
                              f'where the arm is (more than {START_TOLERANCE} rad)')
        times, Q = times[1:], Q[1:]
        V = None if V is None else V[1:]
        A = None if A is None else A[1:]
    if not times.size:
        raise TimingError('only a point at time_from_start 0: no time to move')
    if np.any(np.diff(times) <= 0.0):
        raise TimingError('time_from_start must increase strictly from point to point')
    if V is not None and np.any(np.abs(V[-1]) > REST_SPEED):
        raise TimingError('the last point has non-zero velocities (the arm stops there)')
    knots = np.concatenate([[0.0], times])
    q = np.vstack([q_start, Q])
    if V is None:
        spline = CubicSpline(knots, q, axis=0, bc_type=((1, qd_start), (1, np.zeros_like(
            q_start))))
        return PPoly(spline.c, spline.x)
    v = np.vstack([qd_start, V])
    if A is None:
        c = hermite_coefficients(np.diff(knots), q[:-1], v[:-1], q[1:], v[1:])
    else:
        a = np.vstack([np.zeros_like(q_start), A])
        c = hermite_coefficients(np.diff(knots), q[:-1], v[:-1], q[1:], v[1:], a[:-1], a[1:])
    return PPoly(c, knots)


def check_limits(spline: PPoly, velocity_limits: np.ndarray, a_max: np.ndarray,
                 lower: Optional[np.ndarray] = None, upper: Optional[np.ndarray] = None) -> None:
    """Raise ``TimingError`` naming each joint whose speed, acceleration or position breaks."""
    broken = []
    for j in range(spline.c.shape[2]):
        for order, limit, what in ((1, velocity_limits[j], 'speed'),
                                   (2, a_max[j], 'acceleration')):
            lo, hi = peak(spline, order, j)
            worst = max(-lo, hi)
            if worst > limit * (1.0 + LIMIT_MARGIN):
                broken.append(f'joint {j + 1} {what} {worst:.3f} > {limit:.3f}')
        if lower is not None and upper is not None:
            lo, hi = peak(spline, 0, j)
            if lo < lower[j] - 1e-6 or hi > upper[j] + 1e-6:
                broken.append(f'joint {j + 1} passes [{lo:.3f}, {hi:.3f}] rad outside its '
                              f'limits [{lower[j]:.3f}, {upper[j]:.3f}]')
    if broken:
        raise TimingError('the given timing breaks the limits: ' + '; '.join(broken))


def timed_plan(q_start: Sequence[float], waypoints: np.ndarray, timing: Timing,
               velocity_limits: Sequence[float], a_max: float | Sequence[float],
               qd_start: Optional[Sequence[float]] = None,
               lower: Optional[Sequence[float]] = None,
               upper: Optional[Sequence[float]] = None) -> MotionPlan:
    """
    Return the ``MotionPlan`` that reaches each waypoint (N, n) at its time in ``timing``.

    From ``q_start`` (n,) [rad] and ``qd_start`` (n,) [rad/s] (None: at rest); checked against
    ``velocity_limits`` (n,) [rad/s], ``a_max`` [rad/s^2] and, when given, the joint limits
    ``lower`` and ``upper`` (n,) [rad]. Raises ``TimingError`` with the reason when the timing
    cannot be followed within them, ``InvalidInputError`` when the inputs are malformed.
    """
    q_start = np.asarray(q_start, dtype=float)
    n = q_start.size
    Q = np.asarray(waypoints, dtype=float)
    qd_start = np.zeros(n) if qd_start is None else np.asarray(qd_start, dtype=float)
    if Q.ndim != 2 or Q.shape[1] != n or Q.shape[0] != timing.times.size:
        raise InvalidInputError(f'need waypoints ({timing.times.size}, {n}), got {Q.shape}')
    for name in ('velocities', 'accelerations'):
        value = getattr(timing, name)
        if value is not None and value.shape[1] != n:
            raise InvalidInputError(f'{name} need {n} values per point, got {value.shape[1]}')
    if not timing.timed:
        raise TimingError('no point has a time_from_start')
    vlim = as_positive(velocity_limits, 'velocity_limits', n)
    amax = as_positive(a_max, 'a_max', n)
    spline = timed_spline(q_start, qd_start, Q, timing)
    check_limits(spline, vlim, amax,
                 None if lower is None else np.asarray(lower, dtype=float),
                 None if upper is None else np.asarray(upper, dtype=float))
    duration = float(spline.x[-1])
    segment = TimedSegment(spline, duration, Q[-1].copy())
    return MotionPlan((segment,), Q, timing.times.copy())


def plan_demand(law: LawConfig, q_start: Sequence[float], waypoints: np.ndarray,
                velocity_limits: Sequence[float], qd_start: Optional[Sequence[float]] = None,
                timing: Optional[Timing] = None, lower: Optional[Sequence[float]] = None,
                upper: Optional[Sequence[float]] = None) -> tuple[MotionPlan, str]:
    """
    Return ``(plan, note)``: the timed plan when ``timing`` can be followed, else the law's.

    ``note`` is '' for an untimed demand (``timing`` None or all times zero: ``plan_motion``),
    ``status.TIMING_AS_GIVEN`` ('as given') when the timing is followed (``timed_plan``), and
    'time-optimal through the points: <reason>' when it is not (``plan_motion`` through the
    same points).
    """
    if timing is None or not timing.timed:
        return plan_motion(law, q_start, waypoints, velocity_limits, qd_start), ''
    try:
        return timed_plan(q_start, waypoints, timing, velocity_limits, law.a_max, qd_start,
                          lower, upper), TIMING_AS_GIVEN
    except TimingError as err:
        return (plan_motion(law, q_start, waypoints, velocity_limits, qd_start),
                f'time-optimal through the points: {err}')
