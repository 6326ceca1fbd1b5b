"""
The TOPP passes' compiled recurrence gives the very numbers of a step-by-step Python loop.

``greedy_scan_columns`` takes the steps of ``x_{i+1} = max(0, min(cap_i, min_j A_ij x_i + B_ij))``
compiled (numba), with the same operations on the same numbers, so it must agree with the plain
loop bit for bit: on random recurrences with rising pieces only (the backward pass), with
falling ones too (the forward pass), with long stretches below the caps, at the edges (no
steps, nothing below the caps, a start below the first cap), run from the end (the backward
pass's direction), and on a grid of 55,000 steps.
"""

from mover6_control.motion.timing.greedy_scan import greedy_scan_columns
import numpy as np
import pytest


def greedy_scan(x0, A, B, cap):
    """Return the compiled recurrence of pieces by rows (N, J): its columns are the steps."""
    return greedy_scan_columns(x0, np.asarray(A, dtype=float).T, np.asarray(B, dtype=float).T,
                               cap)


def loop(x0, A, B, cap):
    """Return the recurrence one step at a time (the reference)."""
    x = [float(x0)]
    for a_row, b_row, c in zip(A.tolist(), B.tolist(), cap.tolist()):
        low = min(a * x[-1] + b for a, b in zip(a_row, b_row))
        x.append(max(0.0, min(c, low)))
    return np.array(x)


def problem(seed, n=400, pieces=6, falling=0.0, lines=0.0):
    """
    Return a random recurrence: caps that dip often, so that ramps are many and overlap.

    A share ``lines`` of the steps are line steps (every piece of slope 1, as on the path's
    lines), in stretches.
    """
    rng = np.random.default_rng(seed)
    cap = np.abs(1.0 + 0.6 * np.sin(np.arange(n) / rng.uniform(2.0, 15.0))
                 + rng.normal(0.0, 0.3, n))
    cap[rng.random(n) < 0.03] = 0.0            # stops
    A = rng.uniform(0.7, 1.4, (n, pieces))
    A[rng.random((n, pieces)) < falling] *= -rng.uniform(1.0, 50.0)
    B = rng.uniform(0.001, 0.1, (n, pieces))
    on_line = np.repeat(rng.random(n // 20) < lines, 20)[:n]
    A[on_line] = 1.0
    unused = rng.random((n, pieces)) < 0.2
    A[unused], B[unused] = 0.0, np.inf
    return A, B, cap


@pytest.mark.parametrize('seed', range(20))
@pytest.mark.parametrize('falling', [0.0, 0.05, 0.3])
@pytest.mark.parametrize('lines', [0.0, 0.7])
def test_same_numbers_as_the_loop(seed, falling, lines):
    A, B, cap = problem(seed, falling=falling, lines=lines)
    x0 = float(np.random.default_rng(seed).uniform(0.0, 0.5))
    x = greedy_scan(x0, A, B, cap)
    ref = loop(x0, A, B, cap)
    assert np.array_equal(x, ref), np.flatnonzero(x != ref)[:10]


def test_long_ramps_over_lines():
    # Few ramps, thousands of steps each, mostly over line steps (a long, smooth path).
    n = 5000
    cap = np.full(n, 50.0)
    cap[[0, 2500, n - 1]] = 0.0
    A = np.ones((n, 3))
    A[1200:1300] = np.linspace(0.9, 1.1, 300).reshape(100, 3)      # a blend
    B = np.random.default_rng(1).uniform(0.001, 0.002, (n, 3))
    x = greedy_scan(0.0, A, B, cap)
    assert np.array_equal(x, loop(0.0, A, B, cap))


def test_ramps_inside_ramps():
    # Every step falls short from its cap (steep caps, slow pieces): each starts a ramp, and
    # only the first is real; the others start inside it.
    n = 200
    cap = np.linspace(0.1, 5.0, n)
    A = np.ones((n, 1))
    B = np.full((n, 1), 0.01)
    x = greedy_scan(0.0, A, B, cap)
    assert np.array_equal(x, loop(0.0, A, B, cap))
    assert np.allclose(x, 0.01 * np.arange(n + 1))      # one ramp from 0, never on a cap


def test_edges():
    empty = np.zeros((0, 3))
    assert greedy_scan(0.3, empty, empty, np.zeros(0)).tolist() == [0.3]
    # Nothing below the caps: every step lands on its cap.
    n = 50
    cap = np.full(n, 2.0)
    A, B = np.ones((n, 2)), np.full((n, 2), 5.0)
    assert greedy_scan(2.0, A, B, cap).tolist() == [2.0] + [2.0] * n
    # A start below the first cap: a ramp from x0.
    x = greedy_scan(0.0, A[:, :1], np.full((n, 1), 0.5), cap)
    assert np.array_equal(x, loop(0.0, A[:, :1], np.full((n, 1), 0.5), cap))
    assert x[1] == 0.5 and x[4] == 2.0


def test_run_from_the_end_is_the_loop_over_the_reversed_steps():
    # The backward pass: x_N = x0, and x_i from x_{i+1} with step i's pieces and cap.
    A, B, cap = problem(7, falling=0.0)
    x = greedy_scan_columns(0.0, A.T, B.T, cap, reverse=True)
    ref = loop(0.0, A[::-1], B[::-1], cap[::-1])[::-1]
    assert np.array_equal(x, ref), np.flatnonzero(x != ref)[:10]
    assert x[-1] == 0.0


def test_a_long_grid_in_both_directions():
    # A 1000-waypoint goal's grid is 20,000 steps, a 10,000-waypoint one's 200,000.
    A, B, cap = problem(11, n=55_000, pieces=12, falling=0.05, lines=0.7)
    for reverse in (False, True):
        x = greedy_scan_columns(0.25, A.T, B.T, cap, reverse=reverse)
        order = slice(None, None, -1) if reverse else slice(None)
        ref = loop(0.25, A[order], B[order], cap[order])[order]
        assert np.array_equal(x, ref)
