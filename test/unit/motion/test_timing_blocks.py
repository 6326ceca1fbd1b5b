"""
The time-optimal timing's parts that were made faster give the very numbers of the plain ones.

Each part below reorders or skips work without changing an operation on a number that counts:
the constraints staged a block of grid intervals at a time, the static range over each
column's finite constraints only, the grid points' limit samples taken from the derivatives at
hand, the smoothing integral computed on first use, and the path evaluated, the arcs
checked and the limit ratios taken a block at a time. Each is compared with the plain
computation bit for bit.
"""

import pickle

from mover6_control.motion import blended_path as blended_path_module
from mover6_control.motion.blended_path import blended_path
from mover6_control.motion.timing import time_optimal
from mover6_control.motion.timing.path_timing import FilteredTiming
import numpy as np

V = np.array([0.524, 0.524, 0.524, 0.524, 0.698, 1.745])


def random_walk(m, seed, clip=None):
    """Return random joint waypoints (m, 6), clipped (joints standing still) when asked."""
    Q = np.cumsum(np.random.default_rng(seed).normal(scale=0.05, size=(m, 6)), axis=0)
    Q -= Q.mean(axis=0)
    return Q if clip is None else np.clip(Q, -clip, clip)


def staged(Q, a=1.0):
    """Return what ``time_parameterize`` hands to ``_pieces``: the ends, delta, a, the caps."""
    path = blended_path(Q, 1e-2, 'arc')
    s_grid, seg = time_optimal._grid(path, max(400, 20 * Q.shape[0]))
    d0 = dict(zip((1, 2), path.evaluate(s_grid[:-1], seg, (1, 2))))
    d1, _ = time_optimal._interval_ends(path, s_grid, seg, d0, (1, 2))
    ends = (d0[1], d0[2], d1[1], d1[2])
    limit = time_optimal._speed_caps(d0[1], V * (1.0 - 1e-3))
    return ends, np.diff(s_grid), np.full(6, a * (1.0 - 1e-3)), limit


def test_pieces_by_blocks_are_those_of_the_whole_grid():
    # 1000 waypoints: about 45,000 intervals, several blocks; joints standing still in places.
    ends, delta, a, limit = staged(random_walk(1000, 3, clip=0.4))
    assert delta.size > 2 * time_optimal._INTERVAL_BLOCK
    (bA, bB, bcap), (fA, fB) = time_optimal._pieces(ends, delta, a, limit)
    # The plain way: every column at once.
    gamma, slope, cap = time_optimal._stage_lines(ends[0].T, ends[1].T, ends[2].T, ends[3].T,
                                                  delta, a)
    s_hi = time_optimal._static_range(gamma, slope, np.minimum(cap, limit))
    keep = time_optimal._distinct_lines(gamma, slope)
    A, B, c = time_optimal._backward_pieces(gamma, slope, keep, delta, s_hi)
    F, G = time_optimal._forward_pieces(gamma, slope, keep, delta)
    for ours, plain in ((bA, A), (bB, B), (bcap, c), (fA, F), (fB, G)):
        assert np.array_equal(ours, plain)


def test_static_range_over_finite_constraints_is_that_over_all_pairs():
    rng = np.random.default_rng(7)
    m, R = 12, 3000
    g = rng.uniform(0.01, 5.0, (m, R))
    s = rng.normal(0.0, 3.0, (m, R))
    # Patterns of joints standing still: both constraints of a joint infinite, on some
    # columns; a few single ones; a column with one finite row left, and one with none.
    still = rng.random((m // 2, R)) < 0.4
    g[np.concatenate([still, still])] = np.inf
    g[rng.integers(0, m, 50), rng.integers(0, R, 50)] = np.inf
    g[1:, 0] = np.inf
    g[:, 1] = np.inf
    s[:, 2] = s[0, 2] + np.arange(m) * 1e-16            # nearly equal slopes
    for tiny in (False, True):
        plain = time_optimal._pair_minimum(g, s, tiny)
        ours = time_optimal._pair_minimum_by_pattern(g, s, tiny)
        assert np.array_equal(ours, plain)
        assert np.isinf(ours[0]) and np.isinf(ours[1])
    # One pattern throughout: all rows finite, or the same joints still everywhere.
    for still_rows in ([], [2, 8], [0, 1, 6, 7]):
        g1 = rng.uniform(0.01, 5.0, (m, R))
        g1[still_rows] = np.inf
        assert np.array_equal(time_optimal._pair_minimum_by_pattern(g1, s, True),
                              time_optimal._pair_minimum(g1, s, True))
    # More patterns than are taken one at a time: all rows at once, the same numbers.
    many = rng.random((m, R)) < 0.3
    g2 = np.where(many, np.inf, g)
    assert np.unique((1 << np.arange(m)) @ np.isfinite(g2)).size > time_optimal._PATTERNS
    assert np.array_equal(time_optimal._pair_minimum_by_pattern(g2, s, True),
                          time_optimal._pair_minimum(g2, s, True))


def timed_on_grid(Q):
    """Return the timing of ``Q`` on its grid, its path and each grid interval's segment."""
    traj = time_optimal.time_parameterize(Q, V, 1.0)
    timing = traj.timing
    while not hasattr(timing, 's_grid'):
        timing = timing.base
    return timing, traj.path, traj.path.segment_of(timing.s_grid[:-1])


def test_grid_points_sampled_from_the_derivatives_at_hand():
    timing, path, seg = timed_on_grid(random_walk(60, 11))
    assert time_optimal._grid_points_at_starts(path, timing, seg)
    # What the profile and the path give at the grid times but the last ...
    s, sd, sdd, _ = timing.profile(timing.t_grid[:-1])
    dq, ddq = path.evaluate(s, path.segment_of(s), (1, 2))
    searched = time_optimal._joint_rates(dq, ddq, sd, sdd)
    # ... is what the derivatives at the intervals' starts give.
    d1, d2 = path.evaluate(timing.s_grid[:-1], seg, (1, 2))
    at_hand = time_optimal._joint_rates(d1, d2, timing.sd[:-1], timing.u)
    for ours, plain in zip(at_hand, searched):
        assert np.array_equal(ours, plain)


def test_grid_points_not_at_the_starts_are_searched():
    # Grid times that do not rise (an interval of no time): the search would find the next
    # interval, so the grid points go through the profile as before.
    timing, path, seg = timed_on_grid(random_walk(20, 2))
    flat = type(timing)(timing.s_grid, timing.sd, timing.u, timing.t_grid.copy())
    flat.t_grid[5] = flat.t_grid[4]
    assert not time_optimal._grid_points_at_starts(path, flat, seg)


def test_smoothing_integral_on_first_use():
    timing, _, _ = timed_on_grid(random_walk(20, 4))
    assert '_cum' not in timing.__dict__          # a timing that is not smoothed: not made
    copy = pickle.loads(pickle.dumps(timing))
    t = timing.t_grid
    dt = np.diff(t)
    pieces = timing.s_grid[:-1] * dt + timing.sd[:-1] * dt ** 2 / 2 + timing.u * dt ** 3 / 6
    cumulative = np.concatenate([[0.0], np.cumsum(pieces)])
    assert np.array_equal(timing.integral(t[:-1]), cumulative[:-1])
    assert np.array_equal(copy.integral(t), timing.integral(t))
    smooth = FilteredTiming(timing, 0.2)
    assert np.all(np.isfinite(smooth.profile(np.linspace(0.0, smooth.duration, 50))[0]))


def test_path_evaluated_by_blocks_is_evaluated_point_by_point():
    path = blended_path(random_walk(2000, 9), 1e-2, 'arc')
    s = np.linspace(0.0, path.length, 3 * _point_block() + 17)
    seg = path.segment_of(s)
    whole = path.evaluate(s, seg)
    for lo in range(0, s.size, 997):           # small calls: no blocks
        part = slice(lo, lo + 997)
        for ours, plain in zip(whole, path.evaluate(s[part], seg[part])):
            assert np.array_equal(ours[part], plain)


def _point_block():
    """Return how many points ``BlendedPath.evaluate`` takes at once."""
    return blended_path_module._POINT_BLOCK


def test_arc_check_and_limit_ratios_by_blocks_are_those_of_all_rows():
    timing, path, seg = timed_on_grid(random_walk(1000, 12))
    ends = path.evaluate(timing.s_grid[:-1], seg, (1, 2)) * 2      # (the starts as ends too)
    arcs = np.flatnonzero(path.is_blend(seg))
    assert arcs.size > 2 * time_optimal._INTERVAL_BLOCK
    ours = time_optimal._arc_intervals_within(path, timing, seg[arcs], arcs, ends, V, 1.0)
    plain = time_optimal._arc_block_within(path, timing, seg[arcs], arcs, ends, V, 1.0)
    assert np.array_equal(ours, plain)
    speed, accel = time_optimal._largest_ratios(ends[0], ends[1], timing.sd[:-1], timing.u,
                                                V, 1.0)
    qd, qdd = time_optimal._joint_rates(ends[0], ends[1], timing.sd[:-1], timing.u)
    assert speed == np.max(np.abs(qd) / V) and accel == np.max(np.abs(qdd) / 1.0)
