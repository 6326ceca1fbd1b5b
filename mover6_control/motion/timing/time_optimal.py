"""
Continuous execution: time-optimal timing of a whole joint path, through every waypoint.

The path is the ``BlendedPath`` through the waypoints (``motion.blended_path``: corners
rounded within ``max_deviation``). The timing along it is TOPP-RA's (Pham and Pham, IEEE T-RO
2018): on a grid of path positions ``s`` [rad of joint-space arc length], with ``x = sdot^2``
and ``u = sddot`` constant per grid interval, a backward pass computes the set of controllable
``x`` at each grid point, and a greedy forward pass takes the largest admissible ``u``; both
passes are one compiled loop each (``motion.timing.greedy_scan``). Joint
velocity and acceleration limits are enforced at both ends of every grid interval. The result
is the time-optimal timing of this path up to the grid resolution (a ``GridTiming``,
``motion.path_timing``).

``time_optimal_bound`` gives a lower bound on the duration of ANY trajectory that visits the
waypoints in order under the same limits, to judge how close to optimal the result is.

Jerk limits (``j_max``): corners are blended by quintics whose curvature vanishes where they
meet the lines (so acceleration can be continuous), the TOPP speed is capped where the path's
third derivative would make jerk large, and the timing is smoothed by a moving average and
verified (see ``_jerk_limited``). That trajectory keeps every limit but is no longer
time-optimal.
"""

from __future__ import annotations

from typing import Callable, Optional, Sequence

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.motion.blended_path import blended_path, distinct_waypoints
from mover6_control.motion.timing import arc_bounds, greedy_scan, topp_pieces
from mover6_control.motion.timing.path_timing import (FilteredTiming, GridTiming, PathTrajectory,
                                                      ScaledTiming)
from mover6_control.motion.timing.trajectories import Limit
from mover6_control.validation import as_finite_array, as_positive
import numpy as np

# Largest tangent turn [rad] across one grid interval on a blend arc.
_MAX_TURN = 0.05
# Limits are enforced at grid points only; between them a blend arc can exceed them by
# O(_MAX_TURN^2 / 8) = 3e-4 relative. Planning to limits this much smaller keeps the whole
# trajectory inside the true limits.
_LIMIT_MARGIN = 1e-3
# The jerk-limited timing is checked on samples: slow it 1 % more than they ask for.
_JERK_MARGIN = 1e-2
# Grid intervals per block of the limit checks' arrays (a (block, n) array stays in the cache).
_INTERVAL_BLOCK = 8192


def _grid(path, n_grid):
    """
    Return grid arc lengths (N + 1,) and the segment of each interval (N,).

    Each segment gets ``ceil(length / ds)`` intervals (at least 2), ``ds`` the path length over
    ``n_grid``; a blend at least enough that its tangent turns by ``_MAX_TURN`` or less per
    interval (a quintic, which turns unevenly, twice that many, and at least 8). Segment ends
    are grid points (the stop corners among them).
    """
    ds = path.length / max(int(n_grid), 1)
    a, b = path.starts[:-1], path.starts[1:]
    count = np.maximum(2, np.ceil((b - a) / ds)).astype(int)
    blends = np.flatnonzero(path.is_blend(np.arange(a.size)))
    if blends.size:
        quintic = path.is_quintic(blends)
        per, least = np.where(quintic, 2.0, 1.0), np.where(quintic, 8, 2)
        count[blends] = np.maximum(np.maximum(count[blends], least),
                                   np.ceil(per * path.turns()[blends] / _MAX_TURN).astype(int))
    seg = np.repeat(np.arange(a.size), count)
    first = np.repeat(np.cumsum(count) - count, count)
    step = ((b - a) / count)[seg]
    s_grid = np.empty(seg.size + 1)
    s_grid[:-1] = (np.arange(seg.size) - first) * step + a[seg]
    s_grid[-1] = path.length
    return s_grid, seg


def _backward_pass(pieces):
    """
    Return the upper ends ``hi`` (N + 1,) of TOPP-RA's controllable sets ``K_k = [0, hi[k]]``.

    ``K_N = {0}``. The lower ends are 0 throughout: x = 0 admits u = 0 at every interval, so
    the next set's lower end never binds. The recurrence (``topp_pieces``) runs from the
    end, solved by ``greedy_scan``.
    """
    A, B, cap = pieces
    return greedy_scan.greedy_scan_columns(0.0, A, B, cap, reverse=True)


def _forward_pass(pieces, delta, hi, x0):
    """
    Return the greedy timing: ``x`` (N + 1,) and ``u`` (N,), the largest admissible ``u``.

    Each step takes the largest ``u`` the upper lines ``gamma + slope x`` allow that still
    lands in the next controllable set ``[0, hi[k + 1]]``: ``x_{k+1} = min(hi_{k+1}, min_j
    ((1 + 2 delta slope_j) x_k + 2 delta gamma_j))`` over the constraints that count
    (``topp_pieces``), solved by ``greedy_scan``.
    """
    A, B = pieces
    x = greedy_scan.greedy_scan_columns(x0, A, B, hi[1:])
    return x, (x[1:] - x[:-1]) / (2.0 * delta)


def time_parameterize(Q: np.ndarray, v_max: Limit, a_max: Limit, j_max: Optional[Limit] = None,
                      qd_start: Optional[Sequence[float]] = None, max_deviation: float = 1e-2,
                      n_grid: Optional[int] = None,
                      path_caps: Optional[Callable] = None) -> PathTrajectory:
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

    ``path_caps(path, s_grid)``, when given, returns more caps on ``sdot^2`` at the grid
    points (N + 1,) (``inf``: none), such as a bound on the tool's speed.
    """
    if j_max is not None and qd_start is not None and np.any(np.asarray(qd_start) != 0.0):
        raise InvalidInputError(
            'time_parameterize: j_max with a moving start (qd_start) is not supported; use '
            'jerk_limited.ruckig_trajectory to blend from the current velocity')
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
    d1, last = _interval_ends(path, s_grid, seg, d0, orders)
    # Velocity caps at grid points: x <= (v_i / |q'_i|)^2, smallest of both sides (an
    # interval's end inside a segment is the next one's start: the same cap).
    cap0 = _speed_caps(d0[1], v)
    cap1 = np.empty(N)
    cap1[:-1] = cap0[1:]
    cap1[last] = _speed_caps(d1[1][last], v)
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
    if path_caps is not None:
        x_cap = np.minimum(x_cap, path_caps(path, s_grid))
    x_cap[_nearest(s_grid, np.asarray(path.stops, dtype=float))] = 0.0
    x_cap[-1] = 0.0
    backward, forward = topp_pieces.pieces((d0[1], d0[2], d1[1], d1[2]), delta, a, x_cap[:-1])
    hi = _backward_pass(backward)
    del backward        # (2n, N) arrays: the memory goes back before the next are made
    x, u = _forward_pass(forward, delta, hi, _start_x(path, qd_start, 0.0, hi[0]))
    del forward
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
                              a / (1.0 - _LIMIT_MARGIN), seg, (d0[1], d0[2], d1[1], d1[2]))
    return _jerk_limited(path, timing, v, a, j)


def _speed_caps(dq, v):
    """
    Return ``min_i (v_i / |dq_i|)^2`` per row of ``dq`` (m, n): the largest x the speeds allow.

    Column by column (a minimum along short rows is slow); the square after the minimum,
    which it commutes with (rounding is monotone).
    """
    with np.errstate(divide='ignore', over='ignore'):
        low = v[0] / np.abs(dq[:, 0])
        for i in range(1, dq.shape[1]):
            np.minimum(low, v[i] / np.abs(dq[:, i]), out=low)
        return low ** 2


def _nearest(s_grid, s):
    """
    Return the index of the grid point nearest each ``s`` (m,), the first of equals.

    What ``argmin(|s_grid - s|)`` gives (``s_grid`` ascending), by bisection.
    """
    right = np.minimum(np.searchsorted(s_grid, s), s_grid.size - 1)
    left = np.maximum(right - 1, 0)
    pick = np.where(np.abs(s_grid[left] - s) <= np.abs(s_grid[right] - s), left, right)
    return np.searchsorted(s_grid, s_grid[pick])       # the first of equal grid points


def _interval_ends(path, s_grid, seg, d0, orders):
    """
    Return the path derivatives at the end of every interval (N, n each), on its own segment.

    Inside a segment an interval's end is the next one's start, on the same segment: those are
    ``d0``'s (the derivatives at the starts); only the ends on a segment's last point are new.
    Also return the intervals that end a segment (those, ascending).
    """
    last = np.append(np.flatnonzero(seg[1:] != seg[:-1]), seg.size - 1)
    new = path.evaluate(s_grid[last + 1], seg[last], orders)
    d1 = {}
    for order, values in zip(orders, new):
        d1[order] = np.empty_like(d0[order])
        d1[order][:-1] = d0[order][1:]
        d1[order][last] = values
    return d1, last


def _within_limits(path, timing, traj, v, a, seg, ends, samples=6):
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
    margin they have at the grid points, and lines need no interior samples. Neither need the
    arc intervals that ``arc_bounds.intervals_within`` shows to be within the limits throughout
    (``ends``: the path's first and second derivatives at both ends of every interval): their
    samples could not raise the factor above 1, nor above a larger one found elsewhere.
    """
    t_grid = timing.t_grid
    frac = np.arange(1, samples + 1) / (samples + 1.0)
    arcs = np.flatnonzero(path.is_blend(seg))
    arcs = arcs[~arc_bounds.intervals_within(path.arc_rows(), timing, seg[arcs], arcs, ends, v,
                                             a)]
    t = (t_grid[arcs, None] + (t_grid[arcs + 1] - t_grid[arcs])[:, None] * frac).ravel()
    if _grid_points_at_starts(path, timing, seg):
        # Sampled at its time, grid point k < N is the start of interval k: its path
        # derivatives are ``ends[0]``, ``ends[1]``; the same numbers, without the search.
        at_grid = _largest_ratios(ends[0], ends[1], timing.sd[:-1], timing.u, v, a)
        t = np.concatenate([t_grid[-1:], t])
    else:
        at_grid = (0.0, 0.0)
        t = np.concatenate([t_grid, t])
    s, sd, sdd, _ = timing.profile(t)
    dq, ddq = path.evaluate(s, path.segment_of(s), (1, 2))
    sampled = _largest_ratios(dq, ddq, sd, sdd, v, a)
    factor = max(1.0, at_grid[0], sampled[0], float(np.sqrt(max(at_grid[1], sampled[1]))))
    if factor <= 1.0:
        return traj
    return PathTrajectory(path, ScaledTiming(timing, factor * (1.0 + 1e-4)))


def _joint_rates(dq, ddq, sd, sdd):
    """Return the joint rates and accelerations (m, n) from the path's and the timing's."""
    sd = sd[:, None]
    return dq * sd, dq * sdd[:, None] + ddq * sd ** 2


def _largest_ratios(dq, ddq, sd, sdd, v, a):
    """
    Return the largest ``|qd| / v`` and ``|qdd| / a`` (``_joint_rates``) over all rows (m,).

    A block of rows at a time (the temporaries stay in the cache); 0 for no rows.
    """
    speed = accel = 0.0
    for lo in range(0, sd.size, _INTERVAL_BLOCK):
        part = slice(lo, lo + _INTERVAL_BLOCK)
        qd, qdd = _joint_rates(dq[part], ddq[part], sd[part], sdd[part])
        speed = max(speed, float(np.max(np.abs(qd) / v)))
        accel = max(accel, float(np.max(np.abs(qdd) / a)))
    return speed, accel


def _grid_points_at_starts(path, timing, seg):
    """
    Return whether ``timing.profile`` at each grid time but the last is interval k's start.

    So it is when the grid times rise strictly (the search finds interval k at its own time,
    where ``tau`` is 0: ``s`` is ``s_grid[k]``, the speed ``sd[k]``, the acceleration
    ``u[k]``) and every grid point lies before its segment's end (the search for the segment
    finds interval k's own: the first point of a segment is its start, the others rise to
    below the end).
    """
    s_grid, t_grid = timing.s_grid, timing.t_grid
    last = np.append(np.flatnonzero(seg[1:] != seg[:-1]), seg.size - 1)
    return bool(np.all(t_grid[1:] > t_grid[:-1])
                and np.all(s_grid[last] < path.starts[seg[last] + 1])
                and np.all(path.starts[1:] > path.starts[:-1]))


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
        _, qd, qdd, jerk = traj.derivatives(t)
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
    Q = distinct_waypoints(Q)
    n = Q.shape[1]
    v = as_positive(v_max, 'v_max', n)
    a = as_positive(a_max, 'a_max', n)
    steps = np.abs(np.diff(Q, axis=0))
    joint_bound = float(np.max(_rest_to_rest_time(steps.sum(axis=0), v, a)))
    segment_bound = float(np.sum(np.max(steps / v, axis=1)))
    return max(joint_bound, segment_bound)
