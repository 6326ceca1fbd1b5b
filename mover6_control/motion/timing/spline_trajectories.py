"""
Multi-point joint trajectories through (or near) every waypoint, as splines of time.

On the ``motion.trajectories`` base (``JointTrajectory``), each a ``SplineTrajectory``:
- ``multipoint_trapezoidal``: linear segments with parabolic blends through via points
  (Craig, ch. 7.3), the multi-point trapezoid of the Jacobians and trajectories report.
- ``cubic_trajectory``, ``quintic_trajectory``: interpolating splines through every waypoint at
  rest at both ends (the Jacobians and trajectories report's multi-point cubic and quintic
  polynomials).
- ``bspline_trajectory``: an approximating B-spline with the waypoints as control points.

Given limits instead of times, the durations are fitted to the exact peak rates of the
piecewise polynomials (``_peaks``), never to sampled ones.
"""

from __future__ import annotations

from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing.trajectories import JointTrajectory, Limit, validate_waypoints
from mover6_control.validation import as_finite_array, as_positive
import numpy as np
from scipy.interpolate import BSpline, CubicSpline, make_interp_spline, PPoly

_PEAK_MARGIN = 1e-9


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
    def derivative_splines(self) -> tuple[tuple, ...]:
        """Return per spline its derivatives 0 to 3 (callables of time, as ``splines`` gave)."""
        return tuple(self._derivs)

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

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``(q, qd)`` (n,) each at one time ``t`` [s], as ``sample(t)[:2]``.

        The same spline calls for the position and velocity only: a scalar spline per joint
        (the multi-point trapezoid) makes each call count, every control tick.
        """
        times = np.array([self._time(t)])
        q = np.concatenate([np.asarray(d[0](times)).reshape(-1) for d in self._derivs])
        qd = np.concatenate([np.asarray(d[1](times)).reshape(-1) for d in self._derivs])
        return q, qd


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
    for derivs in traj.derivative_splines:
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
