"""
The compiled per-interval pieces of the time-optimal timing are the plain array formulation's.

``topp_pieces.pieces`` computes each grid interval's constraints, static range, the lines that
count and both passes' pieces in one compiled loop. ``plain_pieces`` below is the same
mathematics as array operations over all intervals at once (the formulation the timing used
before it was compiled, every pair of lines tried): the two must agree bit for bit, on the
grids of random paths (joints standing still in places, so that lines bound x alone), on
constraints with nearly equal slopes, and through ``time_parameterize`` on the grid timing.
"""

from mover6_control.motion.blended_path import blended_path
from mover6_control.motion.timing import time_optimal, topp_pieces
import numpy as np
import pytest

V = np.array([0.524, 0.524, 0.524, 0.524, 0.698, 1.745])


def plain_pieces(ends, delta, a, limit):
    """Return ``pieces``' results as array operations over all intervals (the reference)."""
    dq0, ddq0, dq1, ddq1 = (np.asarray(e).T for e in ends)
    n, N = dq0.shape
    P = np.concatenate([dq0, dq1 + 2.0 * delta * ddq1])
    C = np.concatenate([ddq0, ddq1])
    A = np.concatenate([a, a])[:, None]
    absP = np.abs(P)
    with np.errstate(divide='ignore', invalid='ignore'):
        gamma, slope = A / absP, -C / P
        small = absP <= 1e-12
        gamma[small], slope[small] = np.inf, 0.0
        x_cap = np.min(np.where(small & (np.abs(C) > 1e-12), A / np.abs(C), np.inf), axis=0)
    # The static range: every pair of finite lines, below the caps.
    bound = np.minimum(x_cap, limit)
    spread = np.max(slope, axis=0) - np.min(slope, axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        low = 2.0 * np.min(gamma, axis=0) / spread
        ratios = [np.where(np.abs(slope[i] - slope[j]) > 1e-15,
                           (gamma[i] + gamma[j]) / np.abs(slope[i] - slope[j]), np.inf)
                  for i in range(2 * n) for j in range(i + 1, 2 * n)]
    pairs = np.min(np.where(np.isfinite(ratios), ratios, np.inf), axis=0)
    s_hi = np.where((spread > 1e-15) & ~(low >= bound), np.minimum(bound, pairs), bound)
    # The lines that count.
    keep = np.isfinite(gamma)
    keep[n:] &= ~((gamma[n:] == gamma[:n]) & (slope[n:] == slope[:n]))
    # The backward pass's pieces.
    inv = 1.0 / (2.0 * delta)
    c = slope + inv
    plus, minus = keep & (c > 1e-15), keep & (c < -1e-15)
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        cap = np.minimum(s_hi, np.min(np.where(minus, gamma / -c, np.inf), axis=0))
        back = np.where(plus, inv / c, 0.0), np.where(plus, gamma / c, np.inf), cap
    # The forward pass's pieces.
    two_d = 2.0 * delta
    forward = (np.where(keep, 1.0 + two_d * slope, 0.0), np.where(keep, two_d * gamma, np.inf))
    return back, forward


def random_walk(m, seed, clip=None):
    """Return random joint waypoints (m, 6), clipped (joints standing still) when asked."""
    Q = np.cumsum(np.random.default_rng(seed).normal(scale=0.05, size=(m, 6)), axis=0)
    Q -= Q.mean(axis=0)
    return Q if clip is None else np.clip(Q, -clip, clip)


def staged(Q, a=1.0):
    """Return what ``time_parameterize`` hands to ``pieces``: the ends, delta, a, the caps."""
    path = blended_path(Q, 1e-2, 'arc')
    s_grid, seg = time_optimal._grid(path, max(400, 20 * Q.shape[0]))
    d0 = dict(zip((1, 2), path.evaluate(s_grid[:-1], seg, (1, 2))))
    d1, _ = time_optimal._interval_ends(path, s_grid, seg, d0, (1, 2))
    ends = (d0[1], d0[2], d1[1], d1[2])
    limit = time_optimal._speed_caps(d0[1], V * (1.0 - 1e-3))
    return ends, np.diff(s_grid), np.full(6, a * (1.0 - 1e-3)), limit


def assert_same(ours, plain):
    """Assert both passes' pieces are the same numbers (bit for bit, inf included)."""
    for mine, ref in zip(ours[0] + ours[1], plain[0] + plain[1]):
        assert mine.shape == ref.shape
        assert np.array_equal(mine, ref), np.argwhere(mine != ref)[:5]


@pytest.mark.parametrize('m, seed, clip', [(20, 1, None), (300, 2, None), (1000, 3, 0.4),
                                           (200, 4, 0.1)])
def test_pieces_are_the_plain_formulations(m, seed, clip):
    # Clipped walks: joints stand still on stretches (their lines bound x alone, or nothing).
    ends, delta, a, limit = staged(random_walk(m, seed, clip))
    assert_same(topp_pieces.pieces(ends, delta, a, limit), plain_pieces(ends, delta, a, limit))


def test_nearly_equal_slopes_and_lines_of_x_alone():
    # Random interval data with a vanishing derivative here and there (a line of x alone),
    # slopes that differ by less than 1e-15 (they bound nothing), and ends that repeat starts.
    rng = np.random.default_rng(9)
    N, n = 4000, 6
    dq0, dq1 = rng.normal(0.0, 1.0, (N, n)), rng.normal(0.0, 1.0, (N, n))
    ddq0, ddq1 = rng.normal(0.0, 3.0, (N, n)), rng.normal(0.0, 3.0, (N, n))
    dq0[rng.random((N, n)) < 0.05] = 0.0
    ddq1[rng.random((N, n)) < 0.05] = 0.0
    same = rng.random(N) < 0.3                         # a line of the path: end = start
    dq1[same], ddq1[same] = dq0[same], 0.0
    ddq0[same] = 0.0
    ddq0[::7, 1] = ddq0[::7, 0] * (1.0 + 1e-16)        # nearly equal slopes
    delta = rng.uniform(1e-4, 1e-2, N)
    a = np.full(n, 0.999)
    limit = rng.uniform(0.01, 20.0, N)
    limit[rng.random(N) < 0.02] = 0.0                  # stops
    ends = (dq0, ddq0, dq1, ddq1)
    assert_same(topp_pieces.pieces(ends, delta, a, limit), plain_pieces(ends, delta, a, limit))


def test_the_timing_is_the_plain_pieces_timing(monkeypatch):
    # Through time_parameterize: the grid timing from the compiled pieces is the one from
    # the plain ones, bit for bit.
    Q = random_walk(150, 6, clip=0.3)
    ours = time_optimal.time_parameterize(Q, V, 1.0)
    monkeypatch.setattr(topp_pieces, 'pieces', plain_pieces)
    plain = time_optimal.time_parameterize(Q, V, 1.0)
    assert ours.duration == plain.duration
    a, b = ours.timing, plain.timing
    while not hasattr(a, 's_grid'):
        a, b = a.base, b.base
    for name in ('s_grid', 'sd', 'u', 't_grid'):
        assert np.array_equal(getattr(a, name), getattr(b, name))
