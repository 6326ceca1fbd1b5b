"""
The passes of the time-optimal timing: a greedy recurrence, one compiled loop over the grid.

Both passes of ``motion.time_optimal`` are one recurrence over the grid, ``x_0`` given and
``x_{i+1} = max(0, min(cap_i, min_j (A_ij x_i + B_ij)))`` (``x = sdot^2``): the backward pass,
run from the end (the largest speed that can still slow down in time; ``A_ij > 0``), and the
forward pass (the largest speed the acceleration limits allow; an ``A_ij`` can be negative).
Each step needs the one before, so the loop is sequential: it is compiled by numba (a loop of
Python floats took 1-2 us a step, 30 ms for a 1000-waypoint goal's passes; compiled, the
20,000 steps take 0.2 ms) and runs without the interpreter lock (``nogil``), so the
controller's tick thread is not held while a demand is timed.

Exact: each step is one multiply, one add and the comparisons, in IEEE double precision as a
Python loop takes them (numba contracts no multiply-add into a fused one unless asked, and
``fastmath`` is off), so the result is the plain loop's, bit for bit
(``test/unit/motion/test_greedy_scan.py``).

The loop is compiled when this module is imported (its one signature is given), from the
on-disk cache after the first time (``__pycache__`` beside this file, or numba's user cache
where that is not writable): a node that imports the timing pays it at start, never in the
middle of a motion.
"""

from __future__ import annotations

import numba
import numpy as np

_SCAN_SIGNATURE = 'float64[::1](float64, float64[:, ::1], float64[:, ::1], float64[::1], boolean)'


@numba.njit(_SCAN_SIGNATURE, cache=True, nogil=True, error_model='numpy')
def _scan(x0, A, B, cap, reverse):  # pragma: no cover (compiled: coverage sees no lines)
    """Return ``x`` (N + 1,) of the recurrence; ``reverse``: stepped from the end (module)."""
    J, N = A.shape
    x = np.empty(N + 1)
    cur = x0
    first = N if reverse else 0
    x[first] = cur
    for k in range(N):
        i = N - 1 - k if reverse else k
        low = cap[i]
        for j in range(J):
            value = A[j, i] * cur + B[j, i]
            if value < low:
                low = value
        cur = low if low > 0.0 else 0.0
        x[i if reverse else i + 1] = cur
    return x


def greedy_scan_columns(x0: float, A: np.ndarray, B: np.ndarray, cap: np.ndarray,
                        reverse: bool = False) -> np.ndarray:
    """
    Return ``x`` (N + 1,) of ``x_{i+1} = max(0, min(cap_i, min_j A_ji x_i + B_ji))``.

    ``A``, ``B`` (J, N): piece j of step i in column i (an unused one: ``A = 0``, ``B = inf``);
    ``cap`` (N,) >= 0. With ``reverse`` the recurrence runs from the end: ``x_N = x0`` and
    ``x_i`` from ``x_{i+1}`` with the pieces and cap of step i (the backward pass).
    """
    def doubles(a):
        return np.ascontiguousarray(a, dtype=np.float64)
    return _scan(float(x0), doubles(A), doubles(B), doubles(cap), bool(reverse))
