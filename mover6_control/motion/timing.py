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

Jerk limits (``j_max``): corners are blended by quintics whose curvature vanishes where they
meet the lines (so acceleration can be continuous), the TOPP speed is capped where the path's
third derivative would make jerk large, and the timing is smoothed by a moving average and
verified (see ``_jerk_limited``). That trajectory keeps every limit but is no longer
time-optimal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.motion.trajectories import JointTrajectory, Limit
from mover6_control.validation import as_finite_array, as_positive
import numpy as np

# Below this turning angle [rad] a corner is treated as straight: the velocity direction jumps
# by less than 1e-6 of the speed, well below anything a drive can resolve.
_STRAIGHT_ANGLE = 1e-6
# Above this turning angle [rad] the path reverses: the arm stops at the corner instead.
_REVERSAL_ANGLE = np.pi - 1e-6


def _frozen(arr):
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr


# Quintic Hermite basis (ascending powers) for p(0), p'(0), p'(1), p(1), with p''(0) = p''(1) = 0.
_HERMITE5 = _frozen([[1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
                     [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
                     [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
                     [0.0, 0.0, 0.0, 10.0, -15.0, 6.0]])
# _FALLING[k][j] = j! / (j - k)!: the factor of sigma^(j - k) in the k-th derivative of sigma^j.
_FALLING = tuple(_frozen([np.prod(np.arange(j - k + 1, j + 1)) if j >= k else 0.0
                          for j in range(6)]) for k in range(4))
# Largest tangent turn [rad] across one grid interval on a blend arc.
_MAX_TURN = 0.05
# Entries converted to a list per call (``_as_list``): short enough that threads switch between.
LIST_CHUNK = 20000
# Limits are enforced at grid points only; between them a blend arc can exceed them by
# O(_MAX_TURN^2 / 8) = 3e-4 relative. Planning to limits this much smaller keeps the whole
# trajectory inside the true limits.
_LIMIT_MARGIN = 1e-3
# The jerk-limited timing is checked on samples: slow it 1 % more than they ask for.
_JERK_MARGIN = 1e-2
# BlendedPath segment kinds, as codes for batch evaluation.
_KIND_CODE = {'line': 0, 'arc': 1, 'quintic': 2}


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
    waypoint_s: tuple       # arc length of the path point nearest each waypoint (m,)

    def __post_init__(self):
        """Stack the lines' and arcs' parameters by segment, for ``evaluate`` in one batch."""
        k, n = len(self.kinds), self.waypoints.shape[1]
        code = np.array([_KIND_CODE[kind] for kind in self.kinds], dtype=int)
        stacks = {name: np.zeros((k, n)) for name in ('p', 'u', 'c', 'x', 'y')}
        radius = np.ones(k)
        for i, kind in enumerate(self.kinds):
            if kind == 'line':
                stacks['p'][i], stacks['u'][i] = self.params[i]
            elif kind == 'arc':
                stacks['c'][i], radius[i], stacks['x'][i], stacks['y'][i] = self.params[i]
        object.__setattr__(self, '_code', code)
        object.__setattr__(self, '_stacks', stacks)
        object.__setattr__(self, '_radius', radius)

    @property
    def length(self) -> float:
        """Return the total arc length [rad]."""
        return float(self.starts[-1])

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return self.waypoints.shape[1]

    def evaluate(self, s: np.ndarray, segment: np.ndarray,
                 orders: tuple[int, ...] = (0, 1, 2, 3)) -> tuple[np.ndarray, ...]:
        """
        Return ``q, q', q'', q'''`` (each (m, n)) at arc lengths ``s`` (m,) on ``segment`` (m,).

        Derivatives are with respect to ``s``; each point is evaluated on the given segment,
        so a point on a boundary gets that segment's one-sided derivatives. ``orders`` picks
        which derivatives are computed and returned, in that order. All lines are evaluated in
        one batch, all arcs in another (parameters gathered by segment).
        """
        s = np.asarray(s, dtype=float).reshape(-1)
        segment = np.asarray(segment, dtype=int).reshape(-1)
        n = self.n_joints
        out = {k: np.zeros((s.size, n)) for k in orders}
        code = self._code[segment]
        stacks = self._stacks
        if s.size == 1:         # one point (a control tick): no search by kind
            points = {int(code[0]): np.zeros(1, dtype=int)}
        else:
            points = {kind: np.flatnonzero(code == kind) for kind in range(3)}
        empty = np.zeros(0, dtype=int)
        idx = points.get(0, empty)
        if idx.size:
            seg = segment[idx]
            u = stacks['u'][seg]
            if 0 in out:
                local = (s[idx] - self.starts[seg])[:, None]
                out[0][idx] = stacks['p'][seg] + local * u
            if 1 in out:
                out[1][idx] = u
        idx = points.get(1, empty)
        if idx.size:
            seg = segment[idx]
            local = (s[idx] - self.starts[seg])[:, None]
            x, y = stacks['x'][seg], stacks['y'][seg]
            r = self._radius[seg][:, None]
            phi = local / r
            cos, sin = np.cos(phi), np.sin(phi)
            if 0 in out or 2 in out:
                radial = x * cos + y * sin
                if 0 in out:
                    out[0][idx] = stacks['c'][seg] + r * radial
                if 2 in out:
                    out[2][idx] = -radial / r
            if 1 in out:
                out[1][idx] = -x * sin + y * cos
            if 3 in out:
                out[3][idx] = (x * sin - y * cos) / r ** 2
        idx = points.get(2, empty)
        if idx.size:
            # Quintic blends (jerk limits only): one batch per segment, points grouped by sort.
            idx = idx[np.argsort(segment[idx], kind='stable')]
            for part in np.split(idx, np.flatnonzero(np.diff(segment[idx])) + 1):
                i = segment[part[0]]
                coeffs, scale, _ = self.params[i]
                sigma = (s[part] - self.starts[i])[:, None] / scale
                for k in orders:
                    poly = coeffs[k:] * _FALLING[k][k:, None]
                    powers = sigma ** np.arange(poly.shape[0])
                    out[k][part] = powers @ poly / scale ** k
        return tuple(out[k] for k in orders)

    def turn(self, i: int) -> float:
        """Return how far the tangent turns along segment ``i`` [rad] (0 on a line)."""
        if self.kinds[i] == 'line':
            return 0.0
        if self.kinds[i] == 'quintic':
            return self.params[i][2]
        return float((self.starts[i + 1] - self.starts[i]) / self.params[i][1])

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        """Return the segment index (m,) holding each arc length ``s`` (m,)."""
        idx = np.searchsorted(self.starts, np.asarray(s, dtype=float), side='right') - 1
        return np.minimum(np.maximum(idx, 0), len(self.kinds) - 1)


def _distinct_waypoints(Q):
    Q = as_finite_array(Q, (None, None), 'Q')
    if Q.shape[0] < 2 or Q.shape[1] < 1:
        raise InvalidInputError(f'Q needs at least two waypoints of >= 1 joint, got {Q.shape}')
    keep = np.concatenate([[True], np.linalg.norm(np.diff(Q, axis=0), axis=1) > 1e-12])
    Q = Q[keep]
    if Q.shape[0] < 2:
        raise InvalidInputError('all waypoints coincide: there is no path to time')
    return Q


def _quintic_blend(corner, y1, y2, ell):
    """Return the coefficients (6, n) of the quintic blend cutting ``ell`` off each side."""
    ends = np.array([corner - ell * y1, 2.0 * ell * y1, 2.0 * ell * y2, corner + ell * y2])
    return _HERMITE5.T @ ends


def _quintic_deviation(alpha):
    """Return how far a quintic blend with ell = 1 strays: from the polyline, or the corner."""
    y1, y2 = np.array([1.0, 0.0]), np.array([np.cos(alpha), np.sin(alpha)])
    sigma = np.linspace(0.0, 1.0, 201)
    pts = (sigma[:, None] ** np.arange(6)) @ _quintic_blend(np.zeros(2), y1, y2, 1.0)
    # Distance to the two rays that meet at the corner (origin).
    d_in = np.linalg.norm(pts - np.maximum(pts @ -y1, 0.0)[:, None] * -y1, axis=1)
    d_out = np.linalg.norm(pts - np.maximum(pts @ y2, 0.0)[:, None] * y2, axis=1)
    # Like the arc, pass the corner within the allowance too (its middle is nearest).
    return max(float(np.max(np.minimum(d_in, d_out))), float(np.min(np.linalg.norm(pts, axis=1))))


def blended_path(Q: np.ndarray, max_deviation: float = 1e-2, blend: str = 'arc') -> BlendedPath:
    """
    Return the ``BlendedPath`` through waypoints ``Q`` (m, n) [rad].

    Each inner corner is replaced by a blend tangent to both neighbouring lines, using at most
    half of either line. ``blend='arc'``: a circular arc at most ``max_deviation`` [rad]
    (joint-space distance) from the corner (Kunz and Stilman); ``blend='quintic'``: a quintic
    whose curvature is zero where it meets the lines (curvature-continuous, so acceleration
    can be continuous: for jerk limits), at most ``max_deviation`` from the polyline.
    Consecutive repeated waypoints are dropped; a full reversal is kept as a corner at which
    the arm stops.
    """
    if blend not in ('arc', 'quintic'):
        raise InvalidInputError(f"blend must be 'arc' or 'quintic', got {blend!r}")
    Q = _distinct_waypoints(Q)
    max_deviation = as_positive(max_deviation, 'max_deviation')
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
        if blend == 'quintic':
            ell = min(0.5 * lengths[i - 1], 0.5 * lengths[i],
                      max_deviation / _quintic_deviation(alpha))
            cut[i] = ell
            arcs[i] = ('quintic', (_quintic_blend(Q[i], y1, y2, ell), 2.0 * ell, alpha),
                       2.0 * ell)
            continue
        # The arc's farthest point from the corner is ell tan(alpha / 4) away.
        ell = min(0.5 * lengths[i - 1], 0.5 * lengths[i], max_deviation / np.tan(0.5 * half))
        r = ell / np.tan(half)
        bis = (y2 - y1) / np.linalg.norm(y2 - y1)
        c = Q[i] + bis * r / np.cos(half)
        start = Q[i] - ell * y1
        x = (start - c) / np.linalg.norm(start - c)
        cut[i] = ell
        arcs[i] = ('arc', (c, r, x, y1), alpha * r)
    kinds, params, seg_len, stops, waypoint_s = [], [], [], [], [0.0]
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
                kind, param, arc_len = arcs[k + 1]
                kinds.append(kind)
                params.append(param)
                seg_len.append(arc_len)
                waypoint_s.append(s + 0.5 * arc_len)    # the arc's middle: nearest the corner
                s += arc_len
            else:
                waypoint_s.append(s)
                if stop_at[k + 1]:
                    stops.append(s)
    starts = np.concatenate([[0.0], np.cumsum(seg_len)])
    waypoint_s.append(float(starts[-1]))
    return BlendedPath(tuple(kinds), tuple(params), starts, tuple(stops), Q, tuple(waypoint_s))


@dataclass(frozen=True, eq=False)
class GridTiming:
    """
    TOPP's timing: path acceleration ``u_k`` constant on grid interval k.

    On interval k the path position is ``s_k + sdot_k tau + u_k tau^2 / 2`` for ``tau`` in
    [0, t_{k+1} - t_k]; before the start it rests at 0, after the end at ``s_grid[-1]``.
    """

    s_grid: np.ndarray      # (N + 1,) [rad]
    sd: np.ndarray          # (N + 1,) path speed at the grid points [rad/s]
    u: np.ndarray           # (N,) path acceleration per interval [rad/s^2]
    t_grid: np.ndarray      # (N + 1,) [s]

    def __post_init__(self):
        """Precompute the integral of s at the grid times (for smoothing)."""
        dt = np.diff(self.t_grid)
        pieces = self.s_grid[:-1] * dt + self.sd[:-1] * dt ** 2 / 2 + self.u * dt ** 3 / 6
        object.__setattr__(self, '_cum', np.concatenate([[0.0], np.cumsum(pieces)]))

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return float(self.t_grid[-1])

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        # np.minimum / np.maximum rather than np.clip: several times faster on the one-element
        # arrays of a control tick.
        t = np.asarray(t, dtype=float)
        k = np.minimum(np.maximum(np.searchsorted(self.t_grid, t, side='right') - 1, 0),
                       self.u.size - 1)
        t0 = self.t_grid[k]
        tau = np.minimum(np.maximum(t - t0, 0.0), self.t_grid[k + 1] - t0)
        u = self.u[k]
        s = np.minimum(np.maximum(self.s_grid[k] + self.sd[k] * tau + 0.5 * u * tau ** 2,
                                  self.s_grid[k]), self.s_grid[k + 1])
        sd = np.maximum(self.sd[k] + u * tau, 0.0)
        sdd = u.copy()
        before, after = t < 0.0, t > self.duration
        s[before], s[after] = 0.0, self.s_grid[-1]
        sd[before | after] = 0.0
        sdd[before | after] = 0.0
        return s, sd, sdd, np.zeros_like(s)

    def integral(self, t: np.ndarray) -> np.ndarray:
        """Return the integral of ``s`` from 0 to ``t`` (m,) [rad s]; s holds its end after."""
        t = np.asarray(t, dtype=float)
        tc = np.minimum(np.maximum(t, 0.0), self.duration)
        k = np.minimum(np.searchsorted(self.t_grid, tc, side='right') - 1, self.u.size - 1)
        tau = tc - self.t_grid[k]
        part = self.s_grid[k] * tau + self.sd[k] * tau ** 2 / 2 + self.u[k] * tau ** 3 / 6
        return self._cum[k] + part + self.s_grid[-1] * np.maximum(t - self.duration, 0.0)

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the first time [s] at which the path position reaches ``s`` (m,)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.s_grid[-1])
        k = np.clip(np.searchsorted(self.s_grid, s, side='right') - 1, 0, self.u.size - 1)
        ds = s - self.s_grid[k]
        v0, u = self.sd[k], self.u[k]
        # Solve ds = v0 tau + u tau^2 / 2 for the smallest tau >= 0 (stable form).
        disc = np.sqrt(np.maximum(v0 ** 2 + 2.0 * u * ds, 0.0))
        with np.errstate(divide='ignore', invalid='ignore'):
            tau = np.where(v0 + disc > 0.0, 2.0 * ds / (v0 + disc), 0.0)
        return self.t_grid[k] + np.minimum(tau, self.t_grid[k + 1] - self.t_grid[k])


@dataclass(frozen=True, eq=False)
class FilteredTiming:
    """
    A timing smoothed by a moving average over ``window`` [s]: jerk becomes finite.

    ``s_f(t)`` is the mean of ``s`` over [t - window, t], so ``sdddot_f`` is the difference of
    ``sddot`` across the window divided by it. ``s_f`` is a re-timing of the same path: the
    geometry is untouched. The motion lasts ``window`` longer.
    """

    base: GridTiming
    window: float           # [s]

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self.base.duration + self.window

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        t = np.asarray(t, dtype=float)
        w = self.window
        now = self.base.profile(t)
        then = self.base.profile(t - w)
        s = (self.base.integral(t) - self.base.integral(t - w)) / w
        return (np.minimum(np.maximum(s, 0.0), self.base.s_grid[-1]),) + tuple(
            (a - b) / w for a, b in zip(now[:3], then[:3]))

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the time [s] at which the smoothed path position reaches ``s`` (m,)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        t_lo = self.base.time_at(s)               # s_f lags s: s_f(t) = s no earlier ...
        t_hi = np.minimum(t_lo + self.window, self.duration)   # ... and no later than this
        for _ in range(60):
            mid = 0.5 * (t_lo + t_hi)
            below = self.profile(mid)[0] < s
            t_lo, t_hi = np.where(below, mid, t_lo), np.where(below, t_hi, mid)
        return t_hi


@dataclass(frozen=True, eq=False)
class ScaledTiming:
    """A timing slowed down uniformly by ``factor`` >= 1: rates scale by 1 / factor^k."""

    base: object
    factor: float

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self.base.duration * self.factor

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        out = self.base.profile(np.asarray(t, dtype=float) / self.factor)
        return tuple(v / self.factor ** k for k, v in enumerate(out))

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the time [s] at which the path position reaches ``s`` (m,)."""
        return self.base.time_at(s) * self.factor


class PathTrajectory(JointTrajectory):
    """A ``BlendedPath`` followed with a timing ``s(t)`` (``GridTiming`` or a smoothing of it)."""

    def __init__(self, path: BlendedPath, timing: GridTiming | FilteredTiming | ScaledTiming):
        super().__init__(timing.duration, path.n_joints)
        self.path = path
        self.timing = timing

    def _evaluate(self, t):
        s, sd, sdd, sddd = self.timing.profile(t)
        q, dq, ddq, dddq = self.path.evaluate(s, self.path.segment_of(s))
        sd, sdd, sddd = sd[:, None], sdd[:, None], sddd[:, None]
        qd = dq * sd
        qdd = dq * sdd + ddq * sd ** 2
        qddd = dq * sddd + 3.0 * ddq * sd * sdd + dddq * sd ** 3
        return q, qd, qdd, qddd

    @property
    def waypoint_times(self) -> np.ndarray:
        """Return the time [s] at which the arm passes (closest to) each waypoint (m,)."""
        return self.timing.time_at(np.asarray(self.path.waypoint_s))


def _grid(path, n_grid):
    """Return grid arc lengths (N + 1,) and the segment of each interval (N,)."""
    ds = path.length / max(int(n_grid), 1)
    pieces, segs = [], []
    for i, kind in enumerate(path.kinds):
        a, b = path.starts[i], path.starts[i + 1]
        count = max(2, int(np.ceil((b - a) / ds)))
        if kind != 'line':
            # Keep the tangent turn per interval small: limits hold to O(turn^2) in between.
            # A quintic blend turns unevenly, so it gets twice the points.
            per, least = (1.0, 2) if kind == 'arc' else (2.0, 8)
            count = max(count, least, int(np.ceil(per * path.turn(i) / _MAX_TURN)))
        pts = np.linspace(a, b, count + 1)
        pieces.append(pts[:-1])
        segs.append(np.full(count, i))
    s_grid = np.concatenate(pieces + [[path.length]])
    seg = np.concatenate(segs)
    # Make the stop corners grid points (they are segment boundaries already).
    return s_grid, seg


def _stage_lines(dq0, ddq0, dq1, ddq1, delta, a_max):
    """
    Return the acceleration constraints of all intervals as ``|u - slope x| <= gamma``.

    ``gamma`` and ``slope`` are (N, 2n): constraint j of interval k is ``u >= -gamma + slope x``
    and ``u <= gamma + slope x`` (``gamma`` > 0; ``inf`` and slope 0 where it does not involve
    ``u``); a row whose ``u`` coefficient vanishes bounds ``x`` alone and is returned in
    ``x_cap`` (N,). Rows: the acceleration at the start of the interval (``x_k``) and at its
    end (``x_k + 2 delta u``), with the path derivatives of the interval's own segment.
    """
    P = np.hstack([dq0, dq1 + 2.0 * delta[:, None] * ddq1])
    C = np.hstack([ddq0, ddq1])
    A = np.broadcast_to(np.concatenate([a_max, a_max]), P.shape)
    big = np.abs(P) > 1e-12
    Ps = np.where(big, P, 1.0)
    pos = P > 0.0
    gamma = np.where(big, np.where(pos, A, -A) / Ps, np.inf)
    slope = np.where(big, -C / Ps, 0.0)
    flat = ~big & (np.abs(C) > 1e-12)
    with np.errstate(divide='ignore'):
        x_cap = np.min(np.where(flat, A / np.abs(C), np.inf), axis=1)
    return gamma, slope, x_cap


def _static_range(gamma, slope):
    """
    Return, per interval, the x range ``[lo, hi]`` where the acceleration lines admit some u.

    Some u meets ``|u - slope_j x| <= gamma_j`` for all j if and only if every pair i, j has
    ``|slope_i - slope_j| x <= gamma_i + gamma_j``; ``lo`` is 0 (``gamma`` > 0: x = 0 always
    admits u = 0). Rows whose slopes are all equal (lines) have no upper bound.
    """
    N, m = gamma.shape
    hi = np.full(N, np.inf)
    rows = np.flatnonzero(np.max(slope, axis=1) - np.min(slope, axis=1) > 1e-15)
    if rows.size:
        g, s = gamma[rows], slope[rows]
        bound = np.full(rows.size, np.inf)
        for d in range(1, m):           # the pairs (i, i + d)
            diff = np.abs(s[:, :-d] - s[:, d:])
            steep = diff > 1e-15
            ratio = (g[:, :-d] + g[:, d:]) / np.where(steep, diff, 1.0)
            bound = np.minimum(bound, np.min(np.where(steep, ratio, np.inf), axis=1))
        hi[rows] = bound
    return np.zeros(N), hi


def _members(num, den, member):
    """
    Return the entries of ``num`` and ``den`` (N, m) where ``member`` holds, as flat lists.

    Row k's entries are ``[bounds[k]:bounds[k + 1]]`` of each list.
    """
    bounds = np.concatenate([[0], np.cumsum(member.sum(axis=1))]).tolist()
    return _as_list(num[member]), _as_list(den[member]), bounds


def _as_list(values, chunk=LIST_CHUNK):
    """
    Return the 1-D array ``values`` as a list, converted ``chunk`` entries at a time.

    One ``tolist`` of a long path's millions of entries holds the interpreter for up to half a
    second on a loaded machine, and a controller planning in a thread must not stop its ticks
    that long; between chunks the other threads run.
    """
    out = []
    for start in range(0, len(values), chunk):
        out.extend(values[start:start + chunk].tolist())
    return out


def _distinct_lines(gamma, slope):
    """
    Return which constraints (N, 2n) are finite and not a repeat of another in their row.

    On a line the constraint at the end of an interval repeats the one at its start (the
    path's derivatives are constant): it gives the very same bounds, so it is dropped.
    """
    n = gamma.shape[1] // 2
    keep = np.isfinite(gamma)
    keep[:, n:] &= ~((gamma[:, n:] == gamma[:, :n]) & (slope[:, n:] == slope[:, :n]))
    return keep


def _backward_pass(gamma, slope, delta, s_lo, s_hi, s_grid):
    """
    Return TOPP-RA's controllable sets ``K_k = [lo[k], hi[k]]`` (N + 1,) each; ``K_N = {0}``.

    Besides the static range ``[s_lo[k], s_hi[k]]``, ``x_k`` must let ``x_k + 2 delta u`` land
    in ``K_{k+1}`` with some u in ``|u - slope_j x_k| <= gamma_j``: with ``c_j = slope_j +
    1 / (2 delta)``, ``c_j x_k <= hi[k + 1] / (2 delta) + gamma_j`` and ``c_j x_k >= lo[k + 1]
    / (2 delta) - gamma_j``. The recurrence is sequential; all that does not depend on the next
    set (the coefficients, which ones bound from above or below) is computed for all intervals
    at once beforehand, and the steps run on Python floats.
    """
    N = delta.size
    inv = 1.0 / (2.0 * delta)
    c = slope + inv[:, None]
    keep = _distinct_lines(gamma, slope)
    plus, minus = keep & (c > 1e-15), keep & (c < -1e-15)
    # The most common step: K_{k+1} = [0, s_hi[k + 1]] (only the speed caps bind there). Its
    # result, by the same operations as the loop's for all intervals at once, is taken where
    # that is the state.
    top = np.append(s_hi[1:], 0.0)
    l2 = (top * inv)[:, None]
    with np.errstate(invalid='ignore', over='ignore'):
        hi_f = np.minimum(s_hi, np.min(np.where(plus, (l2 + gamma) / c, np.inf), axis=1))
        hi_f = np.minimum(hi_f, np.min(np.where(minus, (0.0 - gamma) / c, np.inf), axis=1))
        lo_f = np.maximum(s_lo, np.max(np.where(minus, (l2 + gamma) / c, -np.inf), axis=1))
        fast = np.isfinite(l2[:, 0]) & ~(lo_f > hi_f * (1.0 + 1e-9) + 1e-15)
    lo_f = np.minimum(lo_f, hi_f)
    g_p, c_p, b_p = _members(gamma, c, plus)
    g_m, c_m, b_m = _members(gamma, c, minus)
    inv, s_lo, s_hi = inv.tolist(), s_lo.tolist(), s_hi.tolist()
    top, fast, lo_f, hi_f = top.tolist(), fast.tolist(), lo_f.tolist(), hi_f.tolist()
    lo = [0.0] * (N + 1)
    hi = [0.0] * (N + 1)
    inf = float('inf')
    for k in range(N - 1, -1, -1):
        if hi[k + 1] == top[k] and lo[k + 1] == 0.0 and fast[k]:
            lo[k], hi[k] = lo_f[k], hi_f[k]
            continue
        lo_k, hi_k = s_lo[k], s_hi[k]
        i, j = b_p[k], b_p[k + 1]
        m_i, m_j = b_m[k], b_m[k + 1]
        # Offsets of the next set's lines; an infinite one (never, in practice) bounds nothing.
        l1 = lo[k + 1] * inv[k]
        if -inf < l1 < inf:
            # With l1 <= 0 these are all <= 0 (gamma > 0): below s_lo >= 0, they cannot bind.
            if l1 > 0.0 and i < j:
                lo_k = max(lo_k, max([(l1 - g) / cj for g, cj in zip(g_p[i:j], c_p[i:j])]))
            if m_i < m_j:
                hi_k = min(hi_k, min([(l1 - g) / cj for g, cj in zip(g_m[m_i:m_j], c_m[m_i:m_j])]))
        l2 = hi[k + 1] * inv[k]
        if -inf < l2 < inf:
            if i < j:
                hi_k = min(hi_k, min([(l2 + g) / cj for g, cj in zip(g_p[i:j], c_p[i:j])]))
            if m_i < m_j:
                lo_k = max(lo_k, max([(l2 + g) / cj for g, cj in zip(g_m[m_i:m_j], c_m[m_i:m_j])]))
        if lo_k > hi_k * (1.0 + 1e-9) + 1e-15:
            raise UnreachableError(
                f'no admissible speed at path position {s_grid[k]:.4f} rad',
                reason='not_controllable', details={'s': float(s_grid[k])})
        lo[k], hi[k] = min(lo_k, hi_k), hi_k
    return np.array(lo), np.array(hi)


def _forward_pass(gamma, slope, delta, lo, hi, x0):
    """
    Return the greedy timing: ``x`` (N + 1,) and ``u`` (N,), the largest admissible ``u``.

    Each step takes the largest ``u`` the upper lines ``gamma + slope x`` allow that still
    lands in the next controllable set (``lo``, ``hi``); the steps run on Python floats.
    """
    N = delta.size
    keep = _distinct_lines(gamma, slope)
    two_d = 2.0 * delta
    # The most common step starts on the upper bound, x_k = hi[k]: its result, by the same
    # operations as the loop's for all intervals at once, is taken where that is the state.
    at = hi[:-1]
    u_f = np.minimum(np.min(np.where(keep, gamma + slope * at[:, None], np.inf), axis=1),
                     (hi[1:] - at) / two_d)
    x_f = np.minimum(np.maximum(np.maximum(at + two_d * u_f, lo[1:]), 0.0), hi[1:])
    u_f = ((x_f - at) / two_d).tolist()
    x_f = x_f.tolist()
    g, s, b = _members(gamma, slope, keep)
    two_d = two_d.tolist()
    lo, hi = lo.tolist(), hi.tolist()
    x = [x0] + [0.0] * N
    u = [0.0] * N
    inf = float('inf')
    for k in range(N):
        xk = x[k]
        if xk == hi[k]:
            x[k + 1], u[k] = x_f[k], u_f[k]
            continue
        i, j = b[k], b[k + 1]
        u_hi = min([gi + si * xk for gi, si in zip(g[i:j], s[i:j])]) if i < j else inf
        u_hi = min(u_hi, (hi[k + 1] - xk) / two_d[k])
        x[k + 1] = x1 = min(max(xk + two_d[k] * u_hi, lo[k + 1], 0.0), hi[k + 1])
        u[k] = (x1 - xk) / two_d[k]
    return np.array(x), np.array(u)


def time_parameterize(Q: np.ndarray, v_max: Limit, a_max: Limit, j_max: Optional[Limit] = None,
                      qd_start: Optional[Sequence[float]] = None, max_deviation: float = 1e-2,
                      n_grid: Optional[int] = None) -> PathTrajectory:
    """
    Return the time-optimal ``PathTrajectory`` along the blended path through ``Q`` (m, n).

    ``v_max`` [rad/s] and ``a_max`` [rad/s^2] are per-joint limits (n,) or scalars. The arm
    starts at rest, or at ``qd_start`` [rad/s] projected on the path tangent (the part across
    the path cannot be followed and is dropped; a speed too high to stop in time is reduced to
    the largest that can), and ends at rest on the last waypoint. ``max_deviation`` [rad]
    bounds the corner arcs; ``n_grid`` sets the TOPP grid (default: 20 points per waypoint,
    at least 400).

    With ``j_max`` [rad/s^3] the time-optimal timing is smoothed by a moving average (see
    ``_jerk_limited``): the path is unchanged, jerk becomes finite and within ``j_max``, and
    the motion is no longer exactly time-optimal (it lasts about ``max(2 a_max / j_max)``
    longer). ``j_max`` with a non-zero ``qd_start`` is refused.
    """
    if j_max is not None and qd_start is not None and np.any(np.asarray(qd_start) != 0.0):
        raise InvalidInputError(
            'time_parameterize: j_max with a moving start (qd_start) is not supported; use '
            'trajectories.ruckig_trajectory to blend from the current velocity')
    path = blended_path(Q, max_deviation, 'arc' if j_max is None else 'quintic')
    n = path.n_joints
    v = as_positive(v_max, 'v_max', n) * (1.0 - _LIMIT_MARGIN)
    a = as_positive(a_max, 'a_max', n) * (1.0 - _LIMIT_MARGIN)
    if n_grid is None:
        n_grid = max(400, 20 * path.waypoints.shape[0])
    s_grid, seg = _grid(path, n_grid)
    N = seg.size
    delta = np.diff(s_grid)
    # One-sided path derivatives at both ends of each interval, within its own segment (the
    # third only for the jerk limits).
    orders = (1, 2) if j_max is None else (1, 2, 3)
    d0 = dict(zip(orders, path.evaluate(s_grid[:-1], seg, orders)))
    d1 = dict(zip(orders, path.evaluate(s_grid[1:], seg, orders)))
    # Velocity caps at grid points: x <= (v_i / |q'_i|)^2, smallest of both sides.
    with np.errstate(divide='ignore', over='ignore'):
        cap0 = np.min((v / np.abs(d0[1])) ** 2, axis=1)
        cap1 = np.min((v / np.abs(d1[1])) ** 2, axis=1)
    x_cap = np.full(N + 1, np.inf)
    x_cap[:-1] = cap0
    x_cap[1:] = np.minimum(x_cap[1:], cap1)
    if j_max is not None:
        # Jerk on a curved blend grows with sdot^3 |d3q/ds3|: cap the speed there so that term
        # takes at most half of the jerk budget (the smoothing below handles the rest).
        j = as_positive(j_max, 'j_max', n) * (1.0 - _LIMIT_MARGIN)
        with np.errstate(divide='ignore', over='ignore'):
            jcap0 = np.min((0.5 * j / np.abs(d0[3])) ** (2.0 / 3.0), axis=1)
            jcap1 = np.min((0.5 * j / np.abs(d1[3])) ** (2.0 / 3.0), axis=1)
        x_cap[:-1] = np.minimum(x_cap[:-1], jcap0)
        x_cap[1:] = np.minimum(x_cap[1:], jcap1)
    for s_stop in path.stops:
        x_cap[np.argmin(np.abs(s_grid - s_stop))] = 0.0
    x_cap[-1] = 0.0
    gamma, slope, cap = _stage_lines(d0[1], d0[2], d1[1], d1[2], delta, a)
    s_lo, s_hi = _static_range(gamma, slope)
    s_hi = np.minimum(np.minimum(s_hi, cap), x_cap[:-1])
    lo, hi = _backward_pass(gamma, slope, delta, s_lo, s_hi, s_grid)
    x, u = _forward_pass(gamma, slope, delta, lo, hi, _start_x(path, qd_start, lo[0], hi[0]))
    sd = np.sqrt(x)
    dt = 2.0 * delta / np.maximum(sd[:-1] + sd[1:], 1e-300)
    if not np.all(np.isfinite(dt)):
        raise UnreachableError('the path cannot be timed: the speed stays zero',
                               reason='not_controllable')
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    timing = GridTiming(s_grid, sd, u, t_grid)
    if j_max is None:
        traj = PathTrajectory(path, timing)
        if qd_start is not None and np.any(np.asarray(qd_start) != 0.0):
            return traj      # scaling time would change the start velocity it must match
        return _within_limits(path, timing, traj, v / (1.0 - _LIMIT_MARGIN),
                              a / (1.0 - _LIMIT_MARGIN), seg)
    return _jerk_limited(path, timing, v, a, j)


def _within_limits(path, timing, traj, v, a, seg, samples=6):
    """
    Return ``traj``, slowed down uniformly if it exceeds ``v`` or ``a`` (n,) between grid points.

    The speed caps hold at the grid points; on a corner arc the tangent turns inside an
    interval and a joint's rate can pass its cap there by a fraction of the 0.1 % margin, or
    (rarely, on a reversal) by more. Each interval on an arc (``seg``: the segment of each
    interval) is sampled at ``samples`` interior points; a violation of the true limits scales
    the whole timing (rates by 1 / factor, accelerations by 1 / factor^2), which keeps the path
    and the rest-to-rest ends. On a line the path's derivative is constant and its curvature
    zero: the joint rates move monotonically between their values at the grid points and the
    accelerations are those at the interval's start, so the limits hold in between with the
    margin they have at the grid points, and lines need no interior samples.
    """
    t_grid = timing.t_grid
    frac = np.arange(1, samples + 1) / (samples + 1.0)
    arcs = np.flatnonzero(path._code[seg] != 0)
    t = np.concatenate([t_grid, (t_grid[arcs, None] + (t_grid[arcs + 1] - t_grid[arcs])[:, None]
                                 * frac).ravel()])
    s, sd, sdd, _ = timing.profile(t)
    dq, ddq = path.evaluate(s, path.segment_of(s), (1, 2))
    sd = sd[:, None]
    qd = dq * sd
    qdd = dq * sdd[:, None] + ddq * sd ** 2
    factor = max(1.0, float(np.max(np.abs(qd) / v)), float(np.sqrt(np.max(np.abs(qdd) / a))))
    if factor <= 1.0:
        return traj
    return PathTrajectory(path, ScaledTiming(timing, factor * (1.0 + 1e-4)))


def _jerk_limited(path, timing, v, a, j):
    """
    Smooth the TOPP timing so joint jerk stays within ``j`` (n,) [rad/s^3].

    A moving average over a window ``w`` turns each step of joint acceleration into a ramp
    (on a line a step of at most ``2 a`` becomes a jerk of at most ``2 a / w``). On the
    blends the tangent turns during the window, so the ramps can be steeper, and the path's
    own curvature adds jerk: each candidate window (1, 1.5 and 2.5 times ``max(2 a / j)``) is
    measured on both sides of every TOPP grid time, of the same shifted by ``w`` and of each
    time the motion crosses a grid point of the path, and midway between them; it is then
    slowed down uniformly (rates scale by 1 / factor^k) until every limit holds with a 1 %
    margin. The shortest result wins.
    """
    base_window = float(np.max(2.0 * a / j))
    mid = 0.5 * (timing.t_grid[1:] + timing.t_grid[:-1])
    s_grid = timing.s_grid
    s_fine = np.sort(np.concatenate([s_grid, 0.5 * (s_grid[1:] + s_grid[:-1])]))
    best = None
    for scale in (1.0, 1.5, 2.5):
        w = scale * base_window
        smooth = FilteredTiming(timing, w)
        # Sample where the timing changes (grid times, shifted by w) and where the path does
        # (the times the smoothed motion crosses the grid points and their midpoints).
        # Rates jump at the grid times: sample both sides of each jump.
        t_path = smooth.time_at(s_fine)
        knots = np.concatenate([timing.t_grid, timing.t_grid + w, t_path])
        eps = 1e-9 * max(smooth.duration, 1.0)
        t = np.unique(np.clip(np.concatenate([knots, knots - eps, mid, mid + w, t_path]),
                              0.0, smooth.duration))
        traj = PathTrajectory(path, smooth)
        _, qd, qdd, jerk = traj._evaluate(t)
        factor = max(1.0, float(np.max(np.abs(qd) / v)),
                     float(np.sqrt(np.max(np.abs(qdd) / a))),
                     float(np.cbrt(np.max(np.abs(jerk) / j))))
        if factor > 1.0:
            factor *= 1.0 + _JERK_MARGIN
            traj = PathTrajectory(path, ScaledTiming(smooth, factor))
        if best is None or traj.duration < best.duration:
            best = traj
    return best


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


def time_optimal_bound(Q: np.ndarray, v_max: Limit, a_max: Limit) -> float:
    """
    Return a lower bound [s] on the duration of any rest-to-rest motion through ``Q`` in order.

    The motion must pass through the waypoints exactly; ``time_parameterize`` cuts corners by up
    to ``max_deviation``, which can save a little more than its 0.1 % limit margin costs on
    paths with many sharp corners.

    Two bounds, the larger is returned: (1) joint i covers at least its total variation
    ``sum_k |Q[k+1, i] - Q[k, i]|``, and its speed obeys the velocity and acceleration limits
    and starts and ends at zero, so it needs at least the bang-bang time for that distance;
    (2) between consecutive waypoints the slowest joint needs ``|dq_i| / v_i``. Neither
    assumes a particular path shape, so no trajectory through the waypoints can be faster.
    """
    Q = _distinct_waypoints(Q)
    n = Q.shape[1]
    v = as_positive(v_max, 'v_max', n)
    a = as_positive(a_max, 'a_max', n)
    steps = np.abs(np.diff(Q, axis=0))
    joint_bound = float(np.max(_rest_to_rest_time(steps.sum(axis=0), v, a)))
    segment_bound = float(np.sum(np.max(steps / v, axis=1)))
    return max(joint_bound, segment_bound)
