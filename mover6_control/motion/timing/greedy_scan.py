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

# Ramps still running below which the rest are stepped on Python floats.
_FEW = 8


def greedy_scan(x0: float, A: np.ndarray, B: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """
    Return ``x`` (N + 1,) of ``x_{i+1} = max(0, min(cap_i, min_j A_ij x_i + B_ij))``.

    ``A``, ``B`` (N, J): the pieces of each step (an unused one: ``A = 0``, ``B = inf``);
    ``cap`` (N,) >= 0. The same as ``greedy_scan_columns`` on ``A.T``, ``B.T``.
    """
    return greedy_scan_columns(x0, np.ascontiguousarray(np.asarray(A).T),
                               np.ascontiguousarray(np.asarray(B).T), cap)


def greedy_scan_columns(x0: float, A: np.ndarray, B: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """
    Return ``x`` (N + 1,) of ``x_{i+1} = max(0, min(cap_i, min_j A_ji x_i + B_ji))``.

    ``A``, ``B`` (J, N): piece j of step i in column i (an unused one: ``A = 0``, ``B = inf``);
    ``cap`` (N,) >= 0. Pieces by rows: the smallest piece of every step is an element-wise
    minimum over J contiguous rows, many times cheaper than a minimum along short rows.
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
    # A ramp is real when the arm is on a cap where it starts: the first one, then the first
    # to start after the end of the last real one (inside it the arm is below the caps and
    # its values hold). A ramp that starts one step after another is real only when that one
    # was not and the real one before it ended right there: walk the first of each run of
    # starts, and any other only when the chain of real ramps comes to it.
    count = starts.size
    ends = np.full(count, -1)
    walk = np.flatnonzero(np.diff(starts, prepend=-2) != 1)
    seen = []
    while True:
        ends[walk], (ramp, position, values) = _walk(A, B, cap, starts[walk], first[walk])
        seen.append((walk[ramp], position, values))
        after = np.searchsorted(starts, ends, side='right')
        real, i, follow = [], 0, after.tolist()
        while i < count and ends[i] >= 0:
            real.append(i)
            i = follow[i]
        if i >= count:
            break
        # Next: the ramps that start right after the end of one walked already (the chain
        # comes to one of them), all at once.
        walk = np.unique(after[ends >= 0])
        walk = walk[walk < count]
        walk = walk[ends[walk] < 0]
    ramp, position, values = (np.concatenate(v) for v in zip(*seen))
    mine = np.zeros(count, dtype=bool)
    mine[real] = True
    mine = mine[ramp]
    x[position[mine]] = values[mine]
    return x


def _step(A, B, cap, x):
    """Return ``min(cap_i, min_j A_ji x_i + B_ji)`` for every step i (N,) from ``x`` (N,)."""
    return np.minimum(cap, np.min(A * x + B, axis=0))


def _walk(A, B, cap, starts, first):
    """
    Step every ramp from its start (positions (W,), values ``first``) until it lands on a cap.

    One array operation per step for all ramps still running; the last few run on Python
    floats (an array operation on a handful of entries costs more than the floats), a stretch
    of line steps at once (``_line_runs``). Return
    each ramp's last position (W,) and every value a ramp passes: ramp, position and value
    (each (V,)).
    """
    N = cap.size
    ends = starts.copy()
    ramp = np.flatnonzero(starts < N)
    step, cur = starts[ramp], first[ramp]
    visits = [(ramp, step, cur)]
    while ramp.size > _FEW:
        low = np.min(A[:, step] * cur + B[:, step], axis=0)
        here = cap[step]
        nxt = np.maximum(np.minimum(here, low), 0.0)
        landed = here <= low
        step = step + 1
        visits.append((ramp, step, nxt))
        done = landed | (step >= N)
        ends[ramp[done]] = step[done]
        keep = ~done
        ramp, step, cur = ramp[keep], step[keep], nxt[keep]
    tail = ([], [], [])
    runs = _line_runs(A, B) if ramp.size else None
    for k, i, x in zip(ramp.tolist(), step.tolist(), cur.tolist()):
        while True:
            if runs is not None and runs[0][i] > i:
                # A stretch of line steps: x_{i+1} = x_i + beta_i until it lands on a cap.
                end, beta = runs[0][i], runs[1]
                values = np.cumsum(np.concatenate([[x], beta[i:end]]))
                landed = np.flatnonzero(cap[i:end] <= values[1:])
                if landed.size:
                    end = i + int(landed[0]) + 1
                    values[end - i] = cap[end - 1]
                tail[0].extend([k] * (end - i))
                tail[1].extend(range(i + 1, end + 1))
                tail[2].extend(values[1:end - i + 1].tolist())
                i, x = end, float(values[end - i])
                if landed.size or i >= N:
                    ends[k] = i
                    break
                continue
            low = min(a * x + b for a, b in zip(A[:, i].tolist(), B[:, i].tolist()))
            here = float(cap[i])
            x = max(min(here, low), 0.0)
            i += 1
            tail[0].append(k)
            tail[1].append(i)
            tail[2].append(x)
            if here <= low or i >= N:
                ends[k] = i
                break
    visits.append(tuple(np.array(v, dtype=t) for v, t in zip(tail, (np.intp, np.intp, float))))
    return ends, tuple(np.concatenate(v) for v in zip(*visits))


def _line_runs(A, B):
    """
    Return, per step, where its stretch of line steps ends (N,), and each step's ``beta`` (N,).

    A line step has every piece of slope 1 (the path's curvature is zero there): its step is
    ``x + min_j B_j``, with the very rounding of the loop (adding to x is monotone, so the
    smallest sum is x plus the smallest B). Stepping a stretch of them is one cumulative sum
    started at x: the same additions in the same order. ``end[i] == i`` where step i is no
    line step.
    """
    N = A.shape[1]
    beta = np.min(B, axis=0)
    line = (np.all((A == 1.0) | ((A == 0.0) & np.isinf(B)), axis=0) & np.isfinite(beta)
            & (beta >= 0.0))        # the floor at 0 never binds
    index = np.arange(N)
    # The first step at or after i that is no line step.
    stop = np.where(line, N, index)
    end = np.minimum.accumulate(stop[::-1])[::-1]
    return end, beta
