"""
Continuous execution: time-optimal timing of a whole joint path, through every waypoint.

The geometric path is the polyline through the joint waypoints with every corner rounded by a
circular arc whose distance from the corner is at most ``max_deviation`` [rad] (Kunz and
Stilman, "Time-optimal trajectory generation for path following with bounded acceleration and
velocity", RSS 2012). The path is tangent-continuous, so the arm can run through the corners
without stopping; between the arcs it is exactly the polyline.

The timing along the path is TOPP-RA's (Pham and Pham, IEEE T-RO 2018): on a grid of path
positions ``s`` [rad of joint-space arc length], with ``x = sdot^2`` and ``u = sddot``
constant per grid interval, a backward pass computes the set of controllable ``x`` at each grid
point, and a greedy forward pass takes the largest admissible ``u``. Joint velocity and
acceleration limits are enforced at both ends of every grid interval. The result is the
time-optimal timing of this path up to the grid resolution.

``time_optimal_bound`` gives a lower bound on the duration of ANY trajectory that visits the
waypoints in order under the same limits, to judge how close to optimal the result is.
"""

from dataclasses import dataclass

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.rotations import as_finite_array
from mover6_control.trajectories import JointTrajectory
import numpy as np

# Below this turning angle [rad] a corner is treated as straight: the velocity direction jumps
# by less than 1e-6 of the speed, well below anything a drive can resolve.
_STRAIGHT_ANGLE = 1e-6
# Above this turning angle [rad] the path reverses: the arm stops at the corner instead.
_REVERSAL_ANGLE = np.pi - 1e-6
# Largest tangent turn [rad] across one grid interval on a blend arc.
_MAX_TURN = 0.05
# Limits are enforced at grid points only; between them a blend arc can exceed them by
# O(_MAX_TURN^2 / 8) = 3e-4 relative. Planning to limits this much smaller keeps the whole
# trajectory inside the true limits.
_LIMIT_MARGIN = 1e-3


@dataclass(frozen=True, eq=False)
class BlendedPath:
    """
    A joint path of lines and circular blends, parameterised by arc length ``s`` [rad].

    Segment ``i`` spans ``s`` in ``[starts[i], starts[i + 1]]``. A line is ``p + s u``; an arc
    is ``c + r (x cos(s / r) + y sin(s / r))``. ``stops`` holds the arc lengths of corners that
    could not be blended (reversals): the arm must be at rest there.
    """

    kinds: tuple            # 'line' or 'arc' per segment
    params: tuple           # per segment: (p, u) for a line, (c, r, x, y) for an arc
    starts: np.ndarray      # (k + 1,) cumulative arc length at the segment ends [rad]
    stops: tuple            # arc lengths where the path has a corner and speed must be zero
    waypoints: np.ndarray   # (m, n) the waypoints actually used (repeats removed)

    @property
    def length(self):
        """Return the total arc length [rad]."""
        return float(self.starts[-1])

    @property
    def n_joints(self):
        """Return the number of joints."""
        return self.waypoints.shape[1]

    def evaluate(self, s, segment):
        """
        Return ``q, q', q'', q'''`` (each (m, n)) at arc lengths ``s`` (m,) on ``segment`` (m,).

        Derivatives are with respect to ``s``; each point is evaluated on the given segment,
        so a point on a boundary gets that segment's one-sided derivatives.
        """
        s = np.asarray(s, dtype=float)
        segment = np.asarray(segment, dtype=int)
        n = self.n_joints
        out = [np.zeros((s.size, n)) for _ in range(4)]
        for i in np.unique(segment):
            mask = segment == i
            local = (s[mask] - self.starts[i])[:, None]
            if self.kinds[i] == 'line':
                p, u = self.params[i]
                out[0][mask] = p + local * u
                out[1][mask] = u
            else:
                c, r, x, y = self.params[i]
                phi = local / r
                cos, sin = np.cos(phi), np.sin(phi)
                out[0][mask] = c + r * (x * cos + y * sin)
                out[1][mask] = -x * sin + y * cos
                out[2][mask] = -(x * cos + y * sin) / r
                out[3][mask] = (x * sin - y * cos) / r ** 2
        return tuple(out)

    def segment_of(self, s):
        """Return the segment index (m,) holding each arc length ``s`` (m,)."""
        idx = np.searchsorted(self.starts, np.asarray(s, dtype=float), side='right') - 1
        return np.clip(idx, 0, len(self.kinds) - 1)


def _distinct_waypoints(Q):
    Q = as_finite_array(Q, (None, None), 'Q')
    if Q.shape[0] < 2 or Q.shape[1] < 1:
        raise InvalidInputError(f'Q needs at least two waypoints of >= 1 joint, got {Q.shape}')
    keep = np.concatenate([[True], np.linalg.norm(np.diff(Q, axis=0), axis=1) > 1e-12])
    Q = Q[keep]
    if Q.shape[0] < 2:
        raise InvalidInputError('all waypoints coincide: there is no path to time')
    return Q


def blended_path(Q, max_deviation=1e-2):
    """
    Return the ``BlendedPath`` through waypoints ``Q`` (m, n) [rad].

    Each inner corner is replaced by a circular arc tangent to both neighbouring lines, at
    most ``max_deviation`` [rad] (joint-space distance) from the corner and using at most
    half of either line. Consecutive repeated waypoints are dropped; a full reversal is kept
    as a corner at which the arm stops.
    """
    Q = _distinct_waypoints(Q)
    max_deviation = float(max_deviation)
    if not np.isfinite(max_deviation) or max_deviation <= 0.0:
        raise InvalidInputError(f'max_deviation must be positive, got {max_deviation}')
    diffs = np.diff(Q, axis=0)
    lengths = np.linalg.norm(diffs, axis=1)
    units = diffs / lengths[:, None]
    m = Q.shape[0]
    cut = np.zeros(m)              # length taken from each side of waypoint i by its blend
    arcs = [None] * m
    stop_at = np.zeros(m, dtype=bool)
    for i in range(1, m - 1):
        y1, y2 = units[i - 1], units[i]
        # The turning angle, accurate for small and large angles alike.
        alpha = 2.0 * float(np.arctan2(np.linalg.norm(y2 - y1), np.linalg.norm(y2 + y1)))
        if alpha < _STRAIGHT_ANGLE:
            continue
        if alpha > _REVERSAL_ANGLE:
            stop_at[i] = True
            continue
        half = 0.5 * alpha
        # The arc's farthest point from the corner is ell tan(alpha / 4) away.
        ell = min(0.5 * lengths[i - 1], 0.5 * lengths[i], max_deviation / np.tan(0.5 * half))
        r = ell / np.tan(half)
        bis = (y2 - y1) / np.linalg.norm(y2 - y1)
        c = Q[i] + bis * r / np.cos(half)
        start = Q[i] - ell * y1
        x = (start - c) / np.linalg.norm(start - c)
        cut[i] = ell
        arcs[i] = (c, r, x, y1, alpha * r)
    kinds, params, seg_len, stops = [], [], [], []
    s = 0.0
    for k in range(m - 1):
        line_len = lengths[k] - cut[k] - cut[k + 1]
        if line_len > 1e-12:
            kinds.append('line')
            params.append((Q[k] + cut[k] * units[k], units[k]))
            seg_len.append(line_len)
            s += line_len
        if k + 1 < m - 1:
            if arcs[k + 1] is not None:
                c, r, x, y, arc_len = arcs[k + 1]
                kinds.append('arc')
                params.append((c, r, x, y))
                seg_len.append(arc_len)
                s += arc_len
            elif stop_at[k + 1]:
                stops.append(s)
    starts = np.concatenate([[0.0], np.cumsum(seg_len)])
    return BlendedPath(tuple(kinds), tuple(params), starts, tuple(stops), Q)


class PathTrajectory(JointTrajectory):
    """
    A ``BlendedPath`` timed by a piecewise-constant path acceleration.

    On grid interval k the path position is ``s_k + sdot_k tau + u_k tau^2 / 2`` for
    ``tau`` in [0, t_{k+1} - t_k].
    """

    def __init__(self, path, s_grid, seg, x, u, t_grid):
        super().__init__(t_grid[-1], path.n_joints)
        self.path = path
        self.s_grid, self.seg, self.x, self.u, self.t_grid = s_grid, seg, x, u, t_grid
        self._sd = np.sqrt(x)

    def _evaluate(self, t):
        k = np.clip(np.searchsorted(self.t_grid, t, side='right') - 1, 0, self.u.size - 1)
        tau = t - self.t_grid[k]
        u = self.u[k]
        sd = np.maximum(self._sd[k] + u * tau, 0.0)
        s = np.clip(self.s_grid[k] + self._sd[k] * tau + 0.5 * u * tau ** 2,
                    self.s_grid[k], self.s_grid[k + 1])
        q, dq, ddq, dddq = self.path.evaluate(s, self.seg[k])
        sd_, u_ = sd[:, None], u[:, None]
        qd = dq * sd_
        qdd = dq * u_ + ddq * sd_ ** 2
        qddd = dddq * sd_ ** 3 + 3.0 * ddq * sd_ * u_
        return q, qd, qdd, qddd

    @property
    def waypoint_times(self):
        """Return the time [s] at which the path passes closest to each waypoint (m,)."""
        W = self.path.waypoints
        t = np.linspace(0.0, self.duration, max(2000, 20 * W.shape[0]))
        q = self.sample(t)[0]
        d = np.linalg.norm(q[None, :, :] - W[:, None, :], axis=2)
        return t[np.argmin(d, axis=1)]


def _grid(path, n_grid):
    """Return grid arc lengths (N + 1,) and the segment of each interval (N,)."""
    ds = path.length / max(int(n_grid), 1)
    pieces, segs = [], []
    for i, kind in enumerate(path.kinds):
        a, b = path.starts[i], path.starts[i + 1]
        count = max(2, int(np.ceil((b - a) / ds)))
        if kind == 'arc':
            # Keep the tangent turn per interval small: limits hold to O(turn^2) in between.
            count = max(count, int(np.ceil((b - a) / path.params[i][1] / _MAX_TURN)))
        pts = np.linspace(a, b, count + 1)
        pieces.append(pts[:-1])
        segs.append(np.full(count, i))
    s_grid = np.concatenate(pieces + [[path.length]])
    seg = np.concatenate(segs)
    # Make the stop corners grid points (they are segment boundaries already).
    return s_grid, seg


def _stage_lines(dq0, ddq0, dq1, ddq1, delta, a_max):
    """
    Return the acceleration constraints of all intervals as lines in x, (N, 2n) each.

    Constraint j of interval k is ``u >= alpha + beta x`` and ``u <= gamma + dlt x``; a row
    whose ``u`` coefficient vanishes bounds ``x`` alone and is returned in ``x_cap`` (N,).
    Rows: the acceleration at the start of the interval (``x_k``) and at its end
    (``x_k + 2 delta u``), with the path derivatives of the interval's own segment.
    """
    P = np.hstack([dq0, dq1 + 2.0 * delta[:, None] * ddq1])
    C = np.hstack([ddq0, ddq1])
    A = np.broadcast_to(np.concatenate([a_max, a_max]), P.shape)
    big = np.abs(P) > 1e-12
    Ps = np.where(big, P, 1.0)
    pos = P > 0.0
    alpha = np.where(big, np.where(pos, -A, A) / Ps, -np.inf)
    gamma = np.where(big, np.where(pos, A, -A) / Ps, np.inf)
    slope = np.where(big, -C / Ps, 0.0)
    flat = ~big & (np.abs(C) > 1e-12)
    with np.errstate(divide='ignore'):
        x_cap = np.min(np.where(flat, A / np.abs(C), np.inf), axis=1)
    return alpha, slope, gamma, slope, x_cap


def _static_range(alpha, beta, gamma, dlt):
    """Return, per interval, the x range where the acceleration lines admit some u."""
    coef = beta[:, :, None] - dlt[:, None, :]
    with np.errstate(invalid='ignore'):
        rhs = gamma[:, None, :] - alpha[:, :, None]
    rhs = np.nan_to_num(rhs, nan=np.inf, posinf=np.inf, neginf=-np.inf)
    up = coef > 1e-15
    down = coef < -1e-15
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = rhs / np.where(up | down, coef, 1.0)
    hi = np.min(np.where(up, ratio, np.inf), axis=(1, 2))
    lo = np.max(np.where(down, ratio, -np.inf), axis=(1, 2))
    bad = np.any(~(up | down) & (rhs < -1e-12), axis=(1, 2))
    lo = np.where(bad, np.inf, np.maximum(lo, 0.0))
    return lo, hi


def time_parameterize(Q, v_max, a_max, j_max=None, qd_start=None, max_deviation=1e-2,
                      n_grid=None):
    """
    Return the time-optimal ``PathTrajectory`` along the blended path through ``Q`` (m, n).

    ``v_max`` [rad/s] and ``a_max`` [rad/s^2] are per-joint limits (n,) or scalars. The arm
    starts at rest, or at ``qd_start`` [rad/s] projected on the path tangent (the part across
    the path cannot be followed and is dropped; a speed too high to stop in time is reduced to
    the largest that can), and ends at rest on the last waypoint. ``max_deviation`` [rad]
    bounds the corner arcs; ``n_grid`` sets the TOPP grid (default: 20 points per waypoint,
    at least 400). Jerk limits are not supported on a path (use
    ``trajectories.ruckig_trajectory`` for jerk-limited point-to-point moves): passing
    ``j_max`` raises.
    """
    if j_max is not None:
        raise InvalidInputError(
            'time_parameterize does not enforce jerk limits; pass j_max=None or use '
            'trajectories.ruckig_trajectory for a jerk-limited move')
    path = blended_path(Q, max_deviation)
    n = path.n_joints
    v = _positive(v_max, n, 'v_max') * (1.0 - _LIMIT_MARGIN)
    a = _positive(a_max, n, 'a_max') * (1.0 - _LIMIT_MARGIN)
    if n_grid is None:
        n_grid = max(400, 20 * path.waypoints.shape[0])
    s_grid, seg = _grid(path, n_grid)
    N = seg.size
    delta = np.diff(s_grid)
    # One-sided path derivatives at both ends of each interval, within its own segment.
    d0 = path.evaluate(s_grid[:-1], seg)
    d1 = path.evaluate(s_grid[1:], seg)
    # Velocity caps at grid points: x <= (v_i / |q'_i|)^2, smallest of both sides.
    with np.errstate(divide='ignore', over='ignore'):
        cap0 = np.min((v / np.abs(d0[1])) ** 2, axis=1)
        cap1 = np.min((v / np.abs(d1[1])) ** 2, axis=1)
    x_cap = np.full(N + 1, np.inf)
    x_cap[:-1] = cap0
    x_cap[1:] = np.minimum(x_cap[1:], cap1)
    for s_stop in path.stops:
        x_cap[np.argmin(np.abs(s_grid - s_stop))] = 0.0
    x_cap[-1] = 0.0
    alpha, beta, gamma, dlt, cap = _stage_lines(d0[1], d0[2], d1[1], d1[2], delta, a)
    s_lo, s_hi = _static_range(alpha, beta, gamma, dlt)
    s_hi = np.minimum(np.minimum(s_hi, cap), x_cap[:-1])
    # Backward pass: controllable sets K_k = [lo[k], hi[k]]. Besides the static range, x_k
    # must let x_k + 2 delta u land in K_{k+1} with an admissible u.
    lo = np.zeros(N + 1)
    hi = np.zeros(N + 1)
    for k in range(N - 1, -1, -1):
        two_d = 2.0 * delta[k]
        inv = 1.0 / two_d
        # Next-set lower line against the joint upper lines, joint lower lines against the
        # next-set upper line.
        c1 = -inv - dlt[k]
        r1 = gamma[k] - lo[k + 1] * inv
        c2 = beta[k] + inv
        r2 = hi[k + 1] * inv - alpha[k]
        cands_hi = [s_hi[k]]
        cands_lo = [s_lo[k]]
        for c, r in ((c1, r1), (c2, r2)):
            ok = np.isfinite(r)
            up = ok & (c > 1e-15)
            down = ok & (c < -1e-15)
            if np.any(up):
                cands_hi.append(float(np.min(r[up] / c[up])))
            if np.any(down):
                cands_lo.append(float(np.max(r[down] / c[down])))
        lo[k], hi[k] = max(cands_lo), min(cands_hi)
        if lo[k] > hi[k] * (1.0 + 1e-9) + 1e-15:
            raise UnreachableError(
                f'no admissible speed at path position {s_grid[k]:.4f} rad',
                reason='not_controllable', details={'s': float(s_grid[k])})
        lo[k] = min(lo[k], hi[k])
    # Forward pass: greedy, largest admissible path acceleration.
    x = np.zeros(N + 1)
    x[0] = _start_x(path, qd_start, lo[0], hi[0])
    u = np.zeros(N)
    for k in range(N):
        two_d = 2.0 * delta[k]
        u_hi = min(float(np.min(gamma[k] + dlt[k] * x[k])), (hi[k + 1] - x[k]) / two_d)
        x[k + 1] = min(max(x[k] + two_d * u_hi, lo[k + 1], 0.0), hi[k + 1])
        u[k] = (x[k + 1] - x[k]) / two_d
    sd = np.sqrt(x)
    dt = 2.0 * delta / np.maximum(sd[:-1] + sd[1:], 1e-300)
    if not np.all(np.isfinite(dt)):
        raise UnreachableError('the path cannot be timed: the speed stays zero',
                               reason='not_controllable')
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    return PathTrajectory(path, s_grid, seg, x, u, t_grid)


def _positive(value, n, name):
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 \
        else as_finite_array(value, (n,), name)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise InvalidInputError(f'{name} must be positive and finite, got {np.asarray(arr)}')
    return np.array(arr, dtype=float)


def _start_x(path, qd_start, lo, hi):
    if qd_start is None:
        return 0.0
    qd = as_finite_array(qd_start, (path.n_joints,), 'qd_start')
    tangent = path.evaluate(np.zeros(1), np.zeros(1, dtype=int))[1][0]
    sd = max(float(qd @ tangent), 0.0)
    return float(np.clip(sd ** 2, lo, hi))


def _rest_to_rest_time(distance, v, a):
    """Return the shortest time [s] to cover ``distance`` from rest to rest (bang-bang)."""
    distance = np.asarray(distance, dtype=float)
    full = distance >= v * v / a
    return np.where(full, distance / v + v / a, 2.0 * np.sqrt(distance / a))


def time_optimal_bound(Q, v_max, a_max):
    """
    Return a lower bound [s] on the duration of any rest-to-rest motion through ``Q`` in order.

    Two bounds, the larger is returned: (1) joint i covers at least its total variation
    ``sum_k |Q[k+1, i] - Q[k, i]|``, and its speed obeys the velocity and acceleration limits
    and starts and ends at zero, so it needs at least the bang-bang time for that distance;
    (2) between consecutive waypoints the slowest joint needs ``|dq_i| / v_i``. Neither
    assumes a particular path shape, so no trajectory through the waypoints can be faster.
    """
    Q = _distinct_waypoints(Q)
    n = Q.shape[1]
    v = _positive(v_max, n, 'v_max')
    a = _positive(a_max, n, 'a_max')
    steps = np.abs(np.diff(Q, axis=0))
    joint_bound = float(np.max(_rest_to_rest_time(steps.sum(axis=0), v, a)))
    segment_bound = float(np.sum(np.max(steps / v, axis=1)))
    return max(joint_bound, segment_bound)
