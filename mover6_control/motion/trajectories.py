"""
Joint-space trajectories: one sampling interface for every way of timing a joint motion.

``JointTrajectory`` is the base: ``duration`` [s], ``n_joints`` and ``sample(t)`` giving
``(q, qd, qdd)`` [rad, rad/s, rad/s^2] for a scalar ``t`` (each (n,)) or an array ``t`` (m,)
(each (m, n)). ``t`` is clamped to [0, duration], so sampling past the end holds the end.

Builders:
- ``point_to_point``: a straight joint move under a time law (the Jacobians and trajectories report
  eq. 29-32).
- ``stop_at_each``: the Mover6 report's scheme, one synchronised time-law move per waypoint pair,
  stopping at every waypoint.
- ``multipoint_trapezoidal``: linear segments with parabolic blends through via points
  (Craig, ch. 7.3), the multi-point trapezoid of the Jacobians and trajectories report.
- ``cubic_trajectory``, ``quintic_trajectory``: interpolating splines through every waypoint at
  rest at both ends (the Jacobians and trajectories report's multi-point cubic and quintic
  polynomials).
- ``bspline_trajectory``: an approximating B-spline with the waypoints as control points.
- ``ruckig_trajectory``: jerk-limited, time-optimal, synchronised point-to-point by ruckig (the
  one ruckig wrapper: the controller's jerk-limited law plays it too).
"""

from __future__ import annotations

import functools
import math
from typing import Callable, Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.motion.time_laws import PolynomialTimeLaw, TrapezoidalTimeLaw
from mover6_control.validation import as_finite_array, as_positive
import numpy as np
import ruckig
from scipy.interpolate import BSpline, CubicSpline, make_interp_spline, PPoly
from scipy.optimize import minimize_scalar

TimeLaw = PolynomialTimeLaw | TrapezoidalTimeLaw
Limit = float | Sequence[float]

# Sampling density used to find peak rates when fitting a trajectory to limits.
_PEAK_SAMPLES = 4001
_PEAK_MARGIN = 1e-9


class JointTrajectory:
    """
    Base of every joint trajectory: clamps time and shapes the output.

    Subclasses implement ``_evaluate(t)`` for a float array ``t`` (m,) already clamped to
    [0, duration], returning ``(q, qd, qdd, qddd)`` each (m, n).
    """

    def __init__(self, duration: float, n_joints: int):
        duration = float(duration)
        if not np.isfinite(duration) or duration < 0.0:
            raise InvalidInputError(f'duration must be finite and >= 0, got {duration}')
        self._duration = duration
        self._n_joints = int(n_joints)

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self._duration

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return self._n_joints

    def _times(self, t):
        t_arr = np.asarray(t, dtype=float)
        if t_arr.ndim > 1:
            raise InvalidInputError(f't must be a scalar or 1-D, got shape {t_arr.shape}')
        if not np.all(np.isfinite(t_arr)):
            raise InvalidInputError('t has non-finite values')
        return np.minimum(np.maximum(np.atleast_1d(t_arr), 0.0), self._duration), t_arr.ndim == 0

    def _time(self, t):
        """Return one time ``t`` [s] as a float clamped to [0, duration] (no arrays)."""
        t = float(t)
        if not math.isfinite(t):
            raise InvalidInputError('t has non-finite values')
        return min(max(t, 0.0), self._duration)

    def _evaluate(self, t):
        raise NotImplementedError

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(q, qd, qdd)`` at time(s) ``t`` [s]: (n,) each for a scalar, else (m, n)."""
        times, scalar = self._times(t)
        q, qd, qdd, _ = self._evaluate(times)
        if scalar:
            return q[0], qd[0], qdd[0]
        return q, qd, qdd

    def sample_jerk(self, t: float | np.ndarray) -> np.ndarray:
        """Return the jerk [rad/s^3] at time(s) ``t``: (n,) for a scalar, else (m, n)."""
        times, scalar = self._times(t)
        jerk = self._evaluate(times)[3]
        return jerk[0] if scalar else jerk

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``(q, qd)`` (n,) each at one time ``t`` [s]: what a control tick needs.

        The same values as ``sample(t)[:2]``; subclasses answer without the array machinery of
        ``sample`` where they can (the controller asks every tick).
        """
        q, qd, _ = self.sample(float(t))
        return q, qd


class TimeLawTrajectory(JointTrajectory):
    """A straight joint move ``q0 -> q1`` in ``duration`` [s] under a time law (eq. 29-32)."""

    def __init__(self, q0: Sequence[float], q1: Sequence[float], duration: float, law: TimeLaw):
        q0 = as_finite_array(q0, (None,), 'q0')
        q1 = as_finite_array(q1, (q0.size,), 'q1')
        super().__init__(as_positive(duration, 'duration'), q0.size)
        self.q0, self.q1, self.law = q0, q1, law

    def _evaluate(self, t):
        T = self._duration
        tau = t / T
        dq = self.q1 - self.q0
        out = [self.q0 + np.outer(self.law.evaluate(tau), dq)]
        for k in (1, 2, 3):
            out.append(np.outer(self.law.evaluate(tau, k), dq) / T ** k)
        return tuple(out)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` (n,) each at one time ``t`` [s] (eq. 29-30)."""
        T = self._duration
        tau = self._time(t) / T
        dq = self.q1 - self.q0
        return (self.q0 + dq * float(self.law.evaluate(tau)),
                dq * float(self.law.evaluate(tau, 1)) / T)


class SplineTrajectory(JointTrajectory):
    """
    A trajectory given by scipy splines of time starting at t = 0.

    ``splines`` is one vector-valued spline (values (m, n)) or a sequence of n scalar splines,
    each with ``derivative(k)`` (``BSpline``, ``PPoly``, ``CubicSpline``).
    """

    def __init__(self, splines: object, duration: float, n_joints: int):
        super().__init__(duration, n_joints)
        parts = tuple(splines) if isinstance(splines, (list, tuple)) else (splines,)
        self._derivs = [tuple(p.derivative(k) if k else p for k in range(4)) for p in parts]

    @property
    def breakpoints(self) -> np.ndarray:
        """Return the sorted times [s] where any spline piece starts or ends."""
        knots = [np.asarray(getattr(d[0], 'x', None) if hasattr(d[0], 'x') else d[0].t)
                 for d in self._derivs]
        pts = np.unique(np.concatenate(knots))
        return pts[(pts >= 0.0) & (pts <= self._duration)]

    def _evaluate(self, t):
        out = []
        for k in range(4):
            cols = [np.asarray(d[k](t)).reshape(t.size, -1) for d in self._derivs]
            out.append(np.hstack(cols))
        return tuple(out)


class PiecewiseTrajectory(JointTrajectory):
    """Trajectories played one after another; each starts where the previous ended."""

    def __init__(self, segments: Sequence[JointTrajectory]):
        segments = tuple(segments)
        if not segments:
            raise InvalidInputError('a piecewise trajectory needs at least one segment')
        n = segments[0].n_joints
        if any(s.n_joints != n for s in segments):
            raise InvalidInputError('segments have different numbers of joints')
        self.segments = segments
        self.starts = np.concatenate([[0.0], np.cumsum([s.duration for s in segments])])
        super().__init__(self.starts[-1], n)

    def _evaluate(self, t):
        idx = np.clip(np.searchsorted(self.starts, t, side='right') - 1, 0, len(self.segments) - 1)
        out = [np.empty((t.size, self._n_joints)) for _ in range(4)]
        for i in np.unique(idx):
            mask = idx == i
            seg = self.segments[i]
            local = np.clip(t[mask] - self.starts[i], 0.0, seg.duration)
            for o, v in zip(out, seg._evaluate(local)):
                o[mask] = v
        return tuple(out)


class RuckigTrajectory(JointTrajectory):
    """A ruckig ``Trajectory`` behind the common interface; jerk is piecewise constant."""

    def __init__(self, trajectory: object, n_joints: int):
        super().__init__(trajectory.duration, n_joints)
        self._trajectory = trajectory

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` (n,) each at one time ``t`` [s], straight from ruckig."""
        q, qd, _ = self._trajectory.at_time(self._time(t))
        return np.asarray(q, dtype=float), np.asarray(qd, dtype=float)

    def _evaluate(self, t):
        q = np.empty((t.size, self._n_joints))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        for i, ti in enumerate(t):
            q[i], qd[i], qdd[i] = self._trajectory.at_time(float(ti))
        return q, qd, qdd, self._jerk(t)

    def _jerk(self, t):
        # Ruckig's acceleration is piecewise linear: a one-sided difference inside a piece is
        # exact. Step away from the end so the difference stays inside [0, duration].
        h = 1e-7
        jerk = np.empty((t.size, self._n_joints))
        for i, ti in enumerate(t):
            lo = min(float(ti), max(self._duration - h, 0.0))
            a0 = np.asarray(self._trajectory.at_time(lo)[2])
            a1 = np.asarray(self._trajectory.at_time(lo + h)[2])
            jerk[i] = (a1 - a0) / h if self._duration > 0.0 else 0.0
        return jerk


def validate_waypoints(Q: np.ndarray, name: str = 'Q', allow_repeats: bool = False) -> np.ndarray:
    """
    Return waypoints ``Q`` (m, n) [rad] as an array, checking m >= 2 and finiteness.

    Unless ``allow_repeats``, consecutive coincident waypoints are an error (a segment of zero
    length has no direction and no duration).
    """
    Q = as_finite_array(Q, (None, None), name)
    if Q.shape[0] < 2:
        raise InvalidInputError(f'{name} needs at least two waypoints, got {Q.shape[0]}')
    if Q.shape[1] < 1:
        raise InvalidInputError(f'{name} needs at least one joint')
    if not allow_repeats:
        steps = np.abs(np.diff(Q, axis=0)).max(axis=1)
        same = np.flatnonzero(steps < 1e-12)
        if same.size:
            raise InvalidInputError(
                f'{name} has coincident consecutive waypoints at rows {same.tolist()} and '
                f'{(same + 1).tolist()}')
    return Q


@functools.lru_cache(maxsize=64)
def law_peaks(law: TimeLaw) -> tuple[float, float]:
    """
    Return (max |s'|, max |s''|) of a time law over tau in [0, 1].

    Remembered per law (laws are frozen), so timing many moves under one law searches once.

    The largest sample is refined by a bounded search between its neighbours, so a peak that
    falls between samples is not underestimated (a duration fitted to it would break a limit).
    """
    tau = np.linspace(0.0, 1.0, _PEAK_SAMPLES)
    peaks = []
    for k in (1, 2):
        values = np.abs(law.evaluate(tau, k))
        i = int(np.argmax(values))
        lo, hi = tau[max(i - 1, 0)], tau[min(i + 1, tau.size - 1)]
        res = minimize_scalar(lambda x, k=k: -abs(float(law.evaluate(x, k))), bounds=(lo, hi),
                              method='bounded', options={'xatol': 1e-12})
        peaks.append(max(float(values[i]), -float(res.fun)))
    return peaks[0], peaks[1]


def point_to_point(q0: Sequence[float], q1: Sequence[float], law: TimeLaw,
                   duration: Optional[float] = None, v_max: Optional[Limit] = None,
                   a_max: Optional[Limit] = None) -> TimeLawTrajectory:
    """
    Return a straight, synchronised joint move from ``q0`` to ``q1`` under ``law``.

    Give ``duration`` [s], or ``v_max`` [rad/s] (and optionally ``a_max`` [rad/s^2]) per joint:
    then the duration is the shortest for which no joint exceeds its limits (all joints start
    and stop together, the Mover6 report eq. 1-2).
    """
    q0 = as_finite_array(q0, (None,), 'q0')
    q1 = as_finite_array(q1, (q0.size,), 'q1')
    if duration is None:
        if v_max is None:
            raise InvalidInputError('give a duration or v_max')
        dq = np.abs(q1 - q0)
        if dq.max() < 1e-12:
            raise InvalidInputError('q0 and q1 coincide: there is no move to time')
        sd, sdd = law_peaks(law)
        duration = float(np.max(dq * sd / as_positive(v_max, 'v_max', q0.size)))
        if a_max is not None:
            t_acc = np.sqrt(np.max(dq * sdd / as_positive(a_max, 'a_max', q0.size)))
            duration = max(duration, float(t_acc))
    return TimeLawTrajectory(q0, q1, duration, law)


def stop_at_each(Q: np.ndarray, law: TimeLaw | Callable[[float], TimeLaw], v_max: Limit,
                 a_max: Optional[Limit] = None) -> PiecewiseTrajectory:
    """
    Return the Mover6 report's scheme: one synchronised ``law`` move per waypoint pair.

    ``law`` is a time law or a callable ``law(duration)`` (e.g. ``time_laws.trapezoidal``, whose
    blend is a fraction of each segment's duration either way).
    """
    Q = validate_waypoints(Q)
    the_law = law(1.0) if callable(law) and not hasattr(law, 'evaluate') else law
    segs = [point_to_point(Q[k], Q[k + 1], the_law, v_max=v_max, a_max=a_max)
            for k in range(Q.shape[0] - 1)]
    return PiecewiseTrajectory(segs)


def _segment_durations(Q, v_max):
    return np.max(np.abs(np.diff(Q, axis=0)) / v_max, axis=1)


def _columns(spline):
    """Return one scalar ``PPoly`` per output column of a (vector-valued) scipy spline."""
    if isinstance(spline, PPoly):
        c = spline.c.reshape(spline.c.shape[0], spline.c.shape[1], -1)
        return [PPoly(c[..., j], spline.x) for j in range(c.shape[2])]
    c = spline.c.reshape(spline.c.shape[0], -1)
    return [PPoly.from_spline(BSpline(spline.t, c[:, j], spline.k))
            for j in range(c.shape[1])]


def _piece_extremes(pp, k, duration):
    """Return max |d^k pp / dt^k| over [0, duration]: piece ends and interior stationary points."""
    d = pp.derivative(k)
    x, c = d.x, d.c
    width = np.diff(x)
    inside = (x[1:] > 0.0) & (x[:-1] < duration) & (width > 0.0)
    if not np.any(inside):
        return 0.0
    h = np.minimum(x[1:], duration) - x[:-1]
    # Value at each piece's left end (local 0) and right end (local h): both one-sided limits
    # count, so a derivative that jumps at a breakpoint is bounded on both sides.
    left = c[-1]
    right = np.zeros_like(left)
    for coef in c:
        right = right * h + coef
    best = float(np.max(np.abs(np.concatenate([left[inside], right[inside]]))))
    roots = d.derivative(1).roots(discontinuity=False, extrapolate=False)
    roots = roots[np.isfinite(roots) & (roots >= 0.0) & (roots <= duration)]
    if roots.size:
        best = max(best, float(np.max(np.abs(d(roots)))))
    return best


def _peaks(traj, orders=(1, 2)):
    """
    Return the exact peak |qd| and |qdd| per joint of a piecewise-polynomial trajectory.

    A sampled maximum misses a peak between samples (a cubic's velocity is quadratic inside a
    piece), and fitting durations to an underestimated peak breaks the limits; so the peaks are
    taken at every piece end (from both sides) and at the roots of the next derivative.
    ``orders`` picks the derivatives (a tuple of 1 and/or 2); one array (n,) per order.
    """
    peaks = tuple([] for _ in orders)
    for derivs in traj._derivs:
        for pp in _columns(derivs[0]):
            for out, k in zip(peaks, orders):
                out.append(_piece_extremes(pp, k, traj.duration))
    return tuple(np.asarray(p) for p in peaks)


def _fit_to_limits(build, durations, v_max, a_max):
    """Scale all segment durations by one factor so the peak rates just meet the limits."""
    traj = build(durations)
    pv, pa = _peaks(traj)
    k = float(np.max(pv / v_max))
    if a_max is not None:
        k = max(k, float(np.sqrt(np.max(pa / a_max))))
    # The peaks are exact; the tiny margin only absorbs rounding in the rescaled spline.
    return build(durations * k * (1.0 + _PEAK_MARGIN)) if k > 0.0 else traj


def _knot_times(Q, times, v_max, name):
    if times is None and v_max is None:
        raise InvalidInputError(f'{name}: give waypoint times or v_max')
    if times is not None:
        times = as_finite_array(times, (Q.shape[0],), 'times')
        if np.any(np.diff(times) <= 0.0):
            raise InvalidInputError(f'times must increase strictly, got {times.tolist()}')
        return times - times[0]
    return None


def _spline_builder(Q, kind, degree=3):
    def build(durations):
        knots = np.concatenate([[0.0], np.cumsum(durations)])
        if kind == 'cubic':
            spline = CubicSpline(knots, Q, axis=0, bc_type='clamped')
        elif kind == 'quintic':
            zero = [(1, np.zeros(Q.shape[1])), (2, np.zeros(Q.shape[1]))]
            spline = make_interp_spline(knots, Q, k=5, bc_type=(zero, zero), axis=0)
        else:
            spline = _clamped_bspline(Q, knots[-1], degree)
        return SplineTrajectory(spline, knots[-1], Q.shape[1])
    return build


def _clamped_bspline(Q, duration, degree):
    # Repeat the end control points so velocity and acceleration vanish at both ends.
    ctrl = np.vstack([Q[:1], Q[:1], Q, Q[-1:], Q[-1:]])
    n_ctrl = ctrl.shape[0]
    inner = np.linspace(0.0, duration, n_ctrl - degree + 1)
    knots = np.concatenate([[0.0] * degree, inner, [duration] * degree])
    return BSpline(knots, ctrl, degree, axis=0)


def _interpolating(Q, times, v_max, a_max, kind, degree=3):
    Q = validate_waypoints(Q)
    fixed = _knot_times(Q, times, v_max, kind)
    build = _spline_builder(Q, kind, degree)
    if fixed is not None:
        return build(np.diff(fixed))
    v = as_positive(v_max, 'v_max', Q.shape[1])
    a = as_positive(a_max, 'a_max', Q.shape[1], allow_none=True)
    return _fit_to_limits(build, _segment_durations(Q, v), v, a)


def cubic_trajectory(Q: np.ndarray, times: Optional[Sequence[float]] = None,
                     v_max: Optional[Limit] = None,
                     a_max: Optional[Limit] = None) -> SplineTrajectory:
    """
    Return a C2 cubic spline through every waypoint of ``Q`` (m, n), at rest at both ends.

    Give ``times`` (m,) [s] for the waypoints, or ``v_max`` [rad/s] (and ``a_max``): then knot
    spacing follows the slowest joint per segment and all times are scaled by one factor so
    the peak rates meet the limits exactly.
    """
    return _interpolating(Q, times, v_max, a_max, 'cubic')


def quintic_trajectory(Q: np.ndarray, times: Optional[Sequence[float]] = None,
                       v_max: Optional[Limit] = None,
                       a_max: Optional[Limit] = None) -> SplineTrajectory:
    """Return a C4 quintic spline through every waypoint, at rest with zero end accelerations."""
    return _interpolating(Q, times, v_max, a_max, 'quintic')


def bspline_trajectory(Q: np.ndarray, duration: Optional[float] = None,
                       v_max: Optional[Limit] = None, a_max: Optional[Limit] = None,
                       degree: int = 3) -> SplineTrajectory:
    """
    Return an approximating B-spline with the waypoints as control points.

    It starts and ends on the first and last waypoint at rest and passes near (not through) the
    inner ones, inside their convex hull: the smoothest of the multi-point options (the Jacobians
    and trajectories report).
    """
    Q = validate_waypoints(Q)
    if int(degree) != degree or not 1 <= degree <= 5:
        raise InvalidInputError(f'degree must be an integer in 1..5, got {degree}')
    build = _spline_builder(Q, 'bspline', int(degree))
    if duration is not None:
        return build(np.array([as_positive(duration, 'duration')]))
    if v_max is None:
        raise InvalidInputError('bspline_trajectory: give a duration or v_max')
    v = as_positive(v_max, 'v_max', Q.shape[1])
    a = as_positive(a_max, 'a_max', Q.shape[1], allow_none=True)
    return _fit_to_limits(build, np.array([_segment_durations(Q, v).sum()]), v, a)


def _lspb_joint(theta, td, acc):
    """Return a PPoly of one joint's linear-with-parabolic-blends path (Craig eq. 7.24-7.32)."""
    m = theta.size
    sgn = np.where(np.diff(theta) >= 0.0, 1.0, -1.0)
    vel = np.empty(m - 1)
    blend = np.empty(m)
    acc_k = np.empty(m)
    d_first, d_last = theta[1] - theta[0], theta[-1] - theta[-2]
    acc_k[0] = sgn[0] * acc
    blend[0] = td[0] - np.sqrt(td[0] ** 2 - 2.0 * d_first / acc_k[0])
    vel[0] = d_first / (td[0] - 0.5 * blend[0])
    acc_k[-1] = -sgn[-1] * acc
    blend[-1] = td[-1] - np.sqrt(td[-1] ** 2 + 2.0 * d_last / acc_k[-1])
    vel[-1] = d_last / (td[-1] - 0.5 * blend[-1])
    for k in range(1, m - 2):
        vel[k] = (theta[k + 1] - theta[k]) / td[k]
    for k in range(1, m - 1):
        dv = vel[k] - vel[k - 1]
        acc_k[k] = acc if dv >= 0.0 else -acc
        blend[k] = dv / acc_k[k]
    # Pieces of constant acceleration: blend 0, line, blend 1, line, ..., blend m-1.
    t_via = np.concatenate([[0.0], np.cumsum(td)])
    edges = [0.0, blend[0]]
    accs = [acc_k[0]]
    for k in range(1, m - 1):
        edges += [t_via[k] - 0.5 * blend[k], t_via[k] + 0.5 * blend[k]]
        accs += [0.0, acc_k[k]]
    edges += [t_via[-1] - blend[-1], t_via[-1]]
    accs += [0.0, acc_k[-1]]
    edges = np.asarray(edges)
    widths = np.diff(edges)
    if np.any(widths < -1e-12):
        return None
    coeffs = np.zeros((3, widths.size))
    p, v = theta[0], 0.0
    for i, (w, a) in enumerate(zip(widths, accs)):
        coeffs[:, i] = (0.5 * a, v, p)
        p, v = p + v * w + 0.5 * a * w * w, v + a * w
    keep = widths > 1e-12
    x = np.concatenate([[edges[0]], edges[1:][keep]])
    return PPoly(coeffs[:, keep], x)


def multipoint_trapezoidal(Q: np.ndarray, v_max: Limit, a_max: Limit,
                           durations: Optional[Sequence[float]] = None) -> SplineTrajectory:
    """
    Return linear segments joined by parabolic blends through the via points of ``Q``.

    Each joint accelerates at ``a_max`` [rad/s^2] in its blends and cruises in between; the
    path starts and ends at rest on the first and last waypoints and passes near the inner
    ones (the blends cut the corners). Segment ``durations`` (m - 1,) [s] default to the
    slowest joint at ``v_max`` [rad/s] and are stretched until every blend fits and no joint
    exceeds ``v_max``.
    """
    Q = validate_waypoints(Q)
    n = Q.shape[1]
    v = as_positive(v_max, 'v_max', n)
    a = as_positive(a_max, 'a_max', n)
    td = _segment_durations(Q, v) if durations is None else \
        as_positive(durations, 'durations', Q.shape[0] - 1)
    for _ in range(200):
        # Blends at either end need td^2 >= 4 |d| / a to fit with room to cruise.
        need = np.sqrt(4.0 * np.abs(Q[[1, -1]] - Q[[0, -2]]) / a).max(axis=1)
        td[0], td[-1] = max(td[0], need[0]), max(td[-1], need[1])
        parts = [_lspb_joint(Q[:, i], td, a[i]) for i in range(n)]
        if all(p is not None for p in parts):
            traj = SplineTrajectory(parts, float(td.sum()), n)
            pv = _peaks(traj, orders=(1,))[0]
            if np.all(pv <= v * (1.0 + 1e-9)):
                return traj
            td = td * min(max(float(np.max(pv / v)), 1.01), 1.5)
        else:
            td = td * 1.1
    raise InvalidInputError('could not fit parabolic blends to these waypoints and limits')


def ruckig_trajectory(q0: Sequence[float], q1: Sequence[float], v_max: Limit, a_max: Limit,
                      j_max: Limit, qd0: Optional[Sequence[float]] = None,
                      qdd0: Optional[Sequence[float]] = None) -> RuckigTrajectory:
    """
    Return ruckig's jerk-limited, time-optimal move from ``q0`` to rest at ``q1``.

    All joints are synchronised (they finish together); ``qd0`` [rad/s] and ``qdd0``
    [rad/s^2] start it from a moving state, e.g. when a new goal preempts a running motion.
    ``v_max`` [rad/s], ``a_max`` [rad/s^2] and ``j_max`` [rad/s^3] are per joint (n,) or one
    value for all.
    """
    q0 = as_finite_array(q0, (None,), 'q0')
    n = q0.size
    q1 = as_finite_array(q1, (n,), 'q1')
    qd0 = np.zeros(n) if qd0 is None else as_finite_array(qd0, (n,), 'qd0')
    qdd0 = np.zeros(n) if qdd0 is None else as_finite_array(qdd0, (n,), 'qdd0')
    inp = ruckig.InputParameter(n)
    inp.current_position = q0.tolist()
    inp.current_velocity = qd0.tolist()
    inp.current_acceleration = qdd0.tolist()
    inp.target_position = q1.tolist()
    inp.target_velocity = [0.0] * n
    inp.target_acceleration = [0.0] * n
    inp.max_velocity = as_positive(v_max, 'v_max', n).tolist()
    inp.max_acceleration = as_positive(a_max, 'a_max', n).tolist()
    inp.max_jerk = as_positive(j_max, 'j_max', n).tolist()
    traj = ruckig.Trajectory(n)
    result = ruckig.Ruckig(n).calculate(inp, traj)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise InvalidInputError(f'ruckig could not plan this move: {result}')
    return RuckigTrajectory(traj, n)
