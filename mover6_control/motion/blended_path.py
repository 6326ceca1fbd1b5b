"""
The geometric path of continuous execution: the joint waypoints' polyline with rounded corners.

Every corner of the polyline through the joint waypoints is rounded by a blend tangent to both
lines: a circular arc whose distance from the corner is at most ``max_deviation`` [rad] (Kunz
and Stilman, "Time-optimal trajectory generation for path following with bounded acceleration
and velocity", RSS 2012), or, for jerk limits, a quintic whose curvature vanishes where it
meets the lines. The path is tangent-continuous, so the arm can run through the corners
without stopping; between the blends it is exactly the polyline. ``motion.time_optimal`` times
it.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.errors import InvalidInputError
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
# Points per block of ``BlendedPath.evaluate`` (its (block, n) temporaries stay in the cache).
_POINT_BLOCK = 8192
# BlendedPath segment kinds, as codes for batch evaluation.
_KIND_CODE = {'line': 0, 'arc': 1, 'quintic': 2}
_KIND_NAME = {code: kind for kind, code in _KIND_CODE.items()}


@dataclass(frozen=True, eq=False)
class BlendedPath:
    """
    A joint path of lines and blends (circular arcs; quintics for jerk limits), by arc length.

    The parameter ``s`` is the joint-space arc length [rad].

    Segment ``i`` spans ``s`` in ``[starts[i], starts[i + 1]]``. A line is ``p + s u``; an arc
    is ``c + r (x cos(s / r) + y sin(s / r))``; a quintic is a polynomial in ``s / length``.
    ``stops`` holds the arc lengths of corners that could not be blended (reversals): the arm
    must be at rest there.
    """

    kinds: tuple            # 'line', 'arc' or 'quintic' per segment
    # per segment: (p, u) for a line, (c, r, x, y) for an arc, (coefficients (6, n), length,
    # turning angle) for a quintic
    params: tuple
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

    def __getstate__(self) -> dict:
        """
        Return the path as a few arrays, for pickling (a plan made in another process).

        Pickled as it is, a path of 10,000 waypoints is 30,000 small objects, and unpickling
        them is one call that holds the interpreter lock for a tenth of a second (the
        controller's tick waits); the lines and arcs are their stacked rows instead, and only
        the quintics (jerk limits, few) keep their parameters.
        """
        quintics = {i: self.params[i] for i, kind in enumerate(self.kinds) if kind == 'quintic'}
        return {'code': self._code, 'stacks': self._stacks, 'radius': self._radius,
                'quintics': quintics, 'starts': self.starts, 'stops': self.stops,
                'waypoints': self.waypoints, 'waypoint_s': self.waypoint_s}

    def __setstate__(self, state: dict) -> None:
        """Rebuild the path from ``__getstate__``'s arrays (the same values, bit for bit)."""
        kinds = tuple(_KIND_NAME[c] for c in state['code'].tolist())
        stacks, radius, quintics = state['stacks'], state['radius'], state['quintics']
        params = []
        for i, kind in enumerate(kinds):        # Python steps: the tick gets the lock between
            if kind == 'line':
                params.append((stacks['p'][i], stacks['u'][i]))
            elif kind == 'arc':
                params.append((stacks['c'][i], radius[i], stacks['x'][i], stacks['y'][i]))
            else:
                params.append(quintics[i])
        for name, value in (('kinds', kinds), ('params', tuple(params)),
                            ('starts', state['starts']), ('stops', state['stops']),
                            ('waypoints', state['waypoints']),
                            ('waypoint_s', state['waypoint_s']), ('_code', state['code']),
                            ('_stacks', stacks), ('_radius', radius)):
            object.__setattr__(self, name, value)

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
        if s.size > _POINT_BLOCK and not np.any(self._code == _KIND_CODE['quintic']):
            # A block of points at a time: the temporaries stay in the cache (the same
            # operations on each point; not with quintics, whose matrix products could sum
            # in another order at another size).
            for lo in range(0, s.size, _POINT_BLOCK):
                part = slice(lo, lo + _POINT_BLOCK)
                for k, values in zip(orders, self.evaluate(s[part], segment[part], orders)):
                    out[k][part] = values
            return tuple(out[k] for k in orders)
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

    def arc_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return every segment's arc vectors ``x``, ``y`` (k, n) and radius (k,) [rad].

        An arc's point at ``phi = s / r`` along it is ``c + r (x cos phi + y sin phi)``, so
        each joint's ``q'`` and ``r q''`` are sinusoids in ``phi`` of amplitude
        ``sqrt(x_i^2 + y_i^2)`` (at most 1); a line's rows are zeros and its radius 1. The
        arrays themselves: read them, never write.
        """
        return self._stacks['x'], self._stacks['y'], self._radius

    def turns(self) -> np.ndarray:
        """Return how far the tangent turns along each segment (k,) [rad] (0 on a line)."""
        out = (self.starts[1:] - self.starts[:-1]) / self._radius
        out[self._code == _KIND_CODE['line']] = 0.0
        for i in np.flatnonzero(self._code == _KIND_CODE['quintic']).tolist():
            out[i] = self.params[i][2]
        return out

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        """Return the segment index (m,) holding each arc length ``s`` (m,)."""
        idx = np.searchsorted(self.starts, np.asarray(s, dtype=float), side='right') - 1
        return np.minimum(np.maximum(idx, 0), len(self.kinds) - 1)

    def is_blend(self, segment: np.ndarray) -> np.ndarray:
        """Return which of the segments ``segment`` (m,) are blends (arc, quintic), not lines."""
        return self._code[np.asarray(segment, dtype=int)] != _KIND_CODE['line']

    def is_quintic(self, segment: np.ndarray) -> np.ndarray:
        """Return which of the segments ``segment`` (m,) are quintic blends."""
        return self._code[np.asarray(segment, dtype=int)] == _KIND_CODE['quintic']


def distinct_waypoints(Q: np.ndarray) -> np.ndarray:
    """Return ``Q`` (m, n) without consecutive repeats; raise when fewer than two are left."""
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
    Q = distinct_waypoints(Q)
    max_deviation = as_positive(max_deviation, 'max_deviation')
    if blend == 'arc':
        return _arc_path(Q, max_deviation)
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
        ell = min(0.5 * lengths[i - 1], 0.5 * lengths[i],
                  max_deviation / _quintic_deviation(alpha))
        cut[i] = ell
        arcs[i] = ('quintic', (_quintic_blend(Q[i], y1, y2, ell), 2.0 * ell, alpha), 2.0 * ell)
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


def _arc_path(Q, max_deviation):
    """
    Return the ``BlendedPath`` through ``Q`` (m, n) with circular arcs, every corner at once.

    The corners of ``blended_path``, as array operations over all of them: a corner turning by
    ``alpha`` gets an arc of radius ``r = ell / tan(alpha / 2)`` that takes ``ell`` (at most
    half of either line, at most ``max_deviation / tan(alpha / 4)``) off both lines; the
    segments are the lines and arcs in turn, those of zero length left out.
    """
    m, n = Q.shape
    diffs = np.diff(Q, axis=0)
    lengths = np.sqrt(np.einsum('ij,ij->i', diffs, diffs))
    units = diffs / lengths[:, None]
    y1, y2 = units[:-1], units[1:]                      # the corners 1 .. m - 2
    turn, across = y2 - y1, y2 + y1
    turn_len = np.sqrt(np.einsum('ij,ij->i', turn, turn))
    alpha = 2.0 * np.arctan2(turn_len, np.sqrt(np.einsum('ij,ij->i', across, across)))
    blend = (alpha >= _STRAIGHT_ANGLE) & (alpha <= _REVERSAL_ANGLE)
    stop = alpha > _REVERSAL_ANGLE
    half = 0.5 * np.where(blend, alpha, 1.0)
    # The arc's farthest point from the corner is ell tan(alpha / 4) away.
    ell = np.minimum(np.minimum(0.5 * lengths[:-1], 0.5 * lengths[1:]),
                     max_deviation / np.tan(0.5 * half))
    r = ell / np.tan(half)
    bisector = turn / np.where(blend, turn_len, 1.0)[:, None]
    centre = Q[1:-1] + bisector * (r / np.cos(half))[:, None]
    radial = Q[1:-1] - ell[:, None] * y1 - centre
    radial /= np.sqrt(np.einsum('ij,ij->i', radial, radial))[:, None]
    cut = np.zeros(m)
    cut[1:-1] = np.where(blend, ell, 0.0)
    # Candidate segments: line 0, arc 1, line 1, arc 2, ..., line m - 2.
    seg_len = np.zeros(2 * m - 3)
    seg_len[0::2] = lengths - cut[:-1] - cut[1:]
    seg_len[1::2] = np.where(blend, alpha * r, 0.0)
    present = np.zeros(2 * m - 3, dtype=bool)
    present[0::2] = seg_len[0::2] > 1e-12
    present[1::2] = blend
    seg_len[~present] = 0.0
    ends = np.cumsum(seg_len)                           # after each candidate
    corner_s = ends[0::2][:-1] + np.where(blend, 0.5 * seg_len[1::2], 0.0)
    kept = np.flatnonzero(present)
    code = (kept % 2).astype(int)                       # 0: line, 1: arc
    k = kept // 2                                       # the line's index, or the arc's - 1
    stacks = {name: np.zeros((kept.size, n)) for name in ('p', 'u', 'c', 'x', 'y')}
    radius = np.ones(kept.size)
    lines, arcs = code == 0, code == 1
    stacks['u'][lines] = units[k[lines]]
    stacks['p'][lines] = Q[k[lines]] + cut[k[lines], None] * units[k[lines]]
    stacks['c'][arcs], stacks['x'][arcs] = centre[k[arcs]], radial[k[arcs]]
    stacks['y'][arcs], radius[arcs] = y1[k[arcs]], r[k[arcs]]
    path = BlendedPath.__new__(BlendedPath)
    path.__setstate__({
        'code': code, 'stacks': stacks, 'radius': radius, 'quintics': {},
        'starts': np.concatenate([[0.0], ends[kept]]),
        'stops': tuple(ends[0::2][:-1][stop].tolist()), 'waypoints': Q,
        'waypoint_s': tuple([0.0] + corner_s.tolist() + [float(ends[-1])])})
    return path
