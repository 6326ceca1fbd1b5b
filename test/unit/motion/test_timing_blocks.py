"""
The time-optimal timing's parts that were made faster give the very numbers of the plain ones.

Each part below reorders or skips work without changing an operation on a number that counts:
the grid points' limit samples taken from the derivatives at
hand, the smoothing integral computed on first use, and the path evaluated and the limit
ratios taken a block at a time. Each is compared with the plain
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


def test_limit_ratios_by_blocks_are_those_of_all_rows():
    timing, path, seg = timed_on_grid(random_walk(1000, 12))
    ends = path.evaluate(timing.s_grid[:-1], seg, (1, 2)) * 2      # (the starts as ends too)
    assert timing.u.size > 2 * time_optimal._INTERVAL_BLOCK
    speed, accel = time_optimal._largest_ratios(ends[0], ends[1], timing.sd[:-1], timing.u,
                                                V, 1.0)
    qd, qdd = time_optimal._joint_rates(ends[0], ends[1], timing.sd[:-1], timing.u)
    assert speed == np.max(np.abs(qd) / V) and accel == np.max(np.abs(qdd) / 1.0)
