"""
The compiled arc check passes the very intervals the array formulation of its bounds passes.

``arc_bounds.intervals_within`` bounds each joint's speed and acceleration inside every arc
interval of a grid timing. ``plain_within`` below computes the same bounds as array operations
over all intervals (the formulation the timing used before it was compiled): the answers must
be the same, on the timing of random paths at their limits, at limits below them (where many
intervals fail), and on a path whose arcs the check lets through only in part.
"""

from mover6_control.motion.blended_path import blended_path
from mover6_control.motion.timing import arc_bounds, time_optimal
import numpy as np
import pytest

V = np.array([0.524, 0.524, 0.524, 0.524, 0.698, 1.745])


def plain_within(path, timing, segment, k, ends, v, a):
    """Return ``intervals_within``'s answer as array operations (the reference)."""
    dq0, ddq0, dq1, ddq1 = (d[k] for d in ends)
    x, y, radius = (values[segment] for values in path.arc_rows())
    amplitude = np.sqrt(x * x + y * y)
    bump = amplitude * ((timing.s_grid[k + 1] - timing.s_grid[k]) / radius)[:, None] ** 2 / 8.0
    sd0, sd1, u = timing.sd[k, None], timing.sd[k + 1, None], timing.u[k, None]
    speed = (np.maximum(np.abs(dq0), np.abs(dq1)) + bump) * np.maximum(sd0, sd1)
    x_top = np.maximum(sd0, sd1) ** 2
    accel = (np.maximum(np.abs(u * dq0 + sd0 ** 2 * ddq0), np.abs(u * dq1 + sd1 ** 2 * ddq1))
             + bump * (5.0 * np.abs(u) + x_top / radius[:, None]))
    return np.all((speed <= v) & (accel <= a), axis=1)


def random_walk(m, seed):
    """Return random joint waypoints (m, 6)."""
    Q = np.cumsum(np.random.default_rng(seed).normal(scale=0.05, size=(m, 6)), axis=0)
    return Q - Q.mean(axis=0)


def arc_intervals(Q, a=1.0):
    """Return the grid timing of ``Q``, its path, the arc intervals, their arcs and the ends."""
    traj = time_optimal.time_parameterize(Q, V, a)
    timing = traj.timing
    while not hasattr(timing, 's_grid'):
        timing = timing.base
    path = traj.path
    seg = path.segment_of(timing.s_grid[:-1])
    d0 = path.evaluate(timing.s_grid[:-1], seg, (1, 2))
    d1 = path.evaluate(timing.s_grid[1:], seg, (1, 2))
    k = np.flatnonzero(path.is_blend(seg))
    return timing, path, k, seg[k], (d0[0], d0[1], d1[0], d1[1])


@pytest.mark.parametrize('m, seed, scale', [(30, 1, 1.0), (300, 2, 1.0), (300, 3, 0.999),
                                            (1000, 4, 0.99), (200, 5, 0.9)])
def test_the_same_intervals_pass(m, seed, scale):
    # At the limits the timing was made for (scale 1) most arc intervals pass; a little
    # below them, the ones that reach the limits fail.
    timing, path, k, segment, ends = arc_intervals(random_walk(m, seed))
    v, a = V * scale, np.full(6, scale)
    ours = arc_bounds.intervals_within(path.arc_rows(), timing, segment, k, ends, v, a)
    plain = plain_within(path, timing, segment, k, ends, v, a)
    assert ours.dtype == bool and ours.shape == k.shape
    assert np.array_equal(ours, plain)
    if scale < 0.995:
        assert 0 < np.count_nonzero(ours) < ours.size      # both answers occur


def test_no_arcs_no_answers():
    path = blended_path(np.array([[0.0] * 6, [0.3] * 6]), 1e-2, 'arc')     # one line
    timing = time_optimal.time_parameterize(path.waypoints, V, 1.0).timing
    none = np.zeros(0, dtype=int)
    ends = (np.zeros((timing.u.size, 6)),) * 4
    assert arc_bounds.intervals_within(path.arc_rows(), timing, none, none, ends, V,
                                       np.ones(6)).size == 0
