"""
The passes of the time-optimal timing as array operations: a greedy recurrence, ramp by ramp.

Both passes of ``motion.time_optimal`` are one recurrence over the grid, ``x_0`` given and
``x_{i+1} = max(0, min(cap_i, min_j (A_ij x_i + B_ij)))`` (``x = sdot^2``): the backward pass,
run from the end (the largest speed that can still slow down in time; ``A_ij > 0``), and the
forward pass (the largest speed the acceleration limits allow; an ``A_ij`` can be negative).
A loop over the grid takes it one step at a time, at Python speed per step.

Most steps land on their cap (the speed limit there, or the controllable set), and a step
that starts on the previous step's cap lands where one array operation over all steps says.
Below the caps the recurrence runs in ramps, each starting where such a step falls short of
its cap. Every ramp is stepped from its start until it lands on a cap again, all ramps at once
(one array operation per step for all that still run), so the cost grows with the longest ramp,
not with the grid. A ramp that starts while an earlier one is still running was never started
(the arm was not on a cap there): the earlier one's values hold. Exact: each value comes from
the same operations on the same numbers as in the loop.
"""

from __future__ import annotations

import numpy as np


def greedy_scan(x0: float, A: np.ndarray, B: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """
    Return ``x`` (N + 1,) of ``x_{i+1} = max(0, min(cap_i, min_j A_ij x_i + B_ij))``.

    ``A``, ``B`` (N, J): the pieces of each step (an unused one: ``A = 0``, ``B = inf``);
    ``cap`` (N,) >= 0.
    """
    N = cap.size
    x = np.empty(N + 1)
    x[0] = x0
    if N == 0:
        return x
    # Every step as if it started on the previous step's cap (step 0: from x0).
    value = np.maximum(_step(A, B, cap, np.concatenate([[x0], cap[:-1]])), 0.0)
    x[1:] = value
    short = np.flatnonzero(value < cap)
    if short.size == 0:
        return x
    starts, first = short + 1, value[short]
    ends = _walk(A, B, cap, starts, first)
    # A ramp is real when the arm is on a cap where it starts: the first one, then the first
    # to start after the end of the last real one (inside it the arm is below the caps and
    # its values hold).
    after = np.searchsorted(starts, ends, side='right').tolist()
    real, i = [], 0
    while i < starts.size:
        real.append(i)
        i = after[i]
    _walk(A, B, cap, starts[real], first[real], x)
    return x


def _step(A, B, cap, x):
    """Return ``min(cap_i, min_j A_ij x_i + B_ij)`` for every step i (N,) from ``x`` (N,)."""
    return np.minimum(cap, np.min(A * x[:, None] + B, axis=1))


def _walk(A, B, cap, starts, first, out=None):
    """
    Step every ramp from its start (positions (W,), values ``first``) until it lands on a cap.

    One array operation per step for all ramps still running. Return each ramp's last
    position (W,); with ``out`` (N + 1,), also write the values it passes into it.
    """
    N = cap.size
    ends = starts.copy()
    ramp = np.flatnonzero(starts < N)
    step, cur = starts[ramp], first[ramp]
    while ramp.size:
        low = np.min(A[step] * cur[:, None] + B[step], axis=1)
        nxt = np.maximum(np.minimum(cap[step], low), 0.0)
        landed = cap[step] <= low
        step = step + 1
        if out is not None:
            out[step] = nxt
        done = landed | (step >= N)
        ends[ramp[done]] = step[done]
        keep = ~done
        ramp, step, cur = ramp[keep], step[keep], nxt[keep]
    return ends
