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
_FEW = 4
# The most steps of a ramp converted to Python floats at once.
_TAIL_BLOCK = 256
# From this many steps on, the ramps read each step's pieces from one row (``by_step``).
_ROWS_FROM = 50_000
# Columns per block of the array operations over all steps (a (J, block) array in the cache).
_STEP_BLOCK = 8192


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
    seen, lines = [], _LineSteps(A, B)
    while True:
        ends[walk], (ramp, position, values) = _walk(A, B, cap, starts[walk], first[walk],
                                                     lines)
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
    """
    Return ``min(cap_i, min_j A_ji x_i + B_ji)`` for every step i (N,) from ``x`` (N,).

    A block of columns at a time: the (J, block) temporaries stay in the cache.
    """
    out = np.empty(cap.size)
    for lo in range(0, cap.size, _STEP_BLOCK):
        part = slice(lo, lo + _STEP_BLOCK)
        t = A[:, part] * x[part]
        t += B[:, part]
        np.minimum.reduce(t, axis=0, out=out[part])
    return np.minimum(cap, out, out=out)


def _walk(A, B, cap, starts, first, lines):
    """
    Step every ramp from its start (positions (W,), values ``first``) until it lands on a cap.

    One array operation per step for all ramps still running, while there are many; the rest
    run on Python floats (``_tail``; ``lines``: the line steps, a ``_LineSteps``). Return each
    ramp's last position (W,) and every value a ramp passes: ramp, position and value (each
    (V,)).
    """
    N = cap.size
    ends = starts.copy()
    ramp = np.flatnonzero(starts < N)
    step, cur = starts[ramp], first[ramp]
    visits = [(ramp, step, cur)]
    lowest = np.minimum.reduce
    J = A.shape[0]
    if ramp.size > _FEW and N >= _ROWS_FROM:
        pieces = lines.by_step()
    while ramp.size > _FEW:
        here = cap[step]
        if N >= _ROWS_FROM:
            # Each step's pieces side by side in a row: a ramp's step reads one row of the
            # memory rather than one entry of each of 2J rows.
            both = pieces[step]
            t = both[:, :J] * cur[:, None]
            t += both[:, J:]
            nxt = lowest(t, axis=1)
        else:
            nxt = lowest(A[:, step] * cur + B[:, step], axis=0)
        landed = here <= nxt
        np.minimum(here, nxt, out=nxt)
        np.maximum(nxt, 0.0, out=nxt)
        step = step + 1
        visits.append((ramp, step, nxt))
        done = landed | (step >= N)
        if done.any():
            ends[ramp[done]] = step[done]
            keep = ~done
            ramp, step, cur = ramp[keep], step[keep], nxt[keep]
        else:
            cur = nxt
    if ramp.size:
        visits.extend(_tail(A, B, cap, ramp.tolist(), step.tolist(), cur.tolist(), ends,
                            lines()))
    return ends, tuple(np.concatenate(v) for v in zip(*visits))


def _tail(A, B, cap, ramps, steps, values, ends, lines):
    """
    Step the few ramps left one at a time on Python floats; return their visits.

    The steps are converted to Python floats a block at a time (the block doubles while the
    ramp runs, up to ``_TAIL_BLOCK`` steps: few are converted past the landing), the pieces
    of line steps not at all: a line step is ``x + beta`` (``lines``: ``beta`` and which steps
    are line steps, ``_LineSteps``). Each ramp's end goes into ``ends``.
    """
    N = cap.size
    beta, line = lines
    out = []
    for k, i, x in zip(ramps, steps, values):
        begin, xs, size, landed = i, [], 16, False
        while not landed and i < N:
            stop = min(N, i + size)
            size = min(2 * size, _TAIL_BLOCK)
            on_line = line[i:stop]
            others = i + np.flatnonzero(~on_line)       # their pieces as Python floats
            pieces = zip(A[:, others].T.tolist(), B[:, others].T.tolist())
            for here, is_line, b in zip(cap[i:stop].tolist(), on_line.tolist(),
                                        beta[i:stop].tolist()):
                if is_line:
                    low = x + b
                else:
                    a_col, b_col = next(pieces)
                    low = min([p * x + q for p, q in zip(a_col, b_col)])
                x = max(min(here, low), 0.0)
                i += 1
                xs.append(x)
                if here <= low:
                    landed = True
                    break
        ends[k] = i
        out.append((np.full(i - begin, k), np.arange(begin + 1, i + 1), np.array(xs)))
    return out


class _LineSteps:
    """
    Each step's smallest ``B`` (N,) and which steps are line steps (N,), found on first use.

    A line step has every piece of slope 1 (the path's curvature is zero there): its step is
    ``x + min_j B_j``, with the very rounding of the loop (``1 * x`` is x, and adding to x is
    monotone, so the smallest sum is x plus the smallest B).
    """

    def __init__(self, A, B):
        """Keep the pieces ``A``, ``B`` (J, N) of the recurrence."""
        self._A, self._B, self._found, self._rows = A, B, None, None

    def by_step(self):
        """Return the pieces of each step side by side, ``[A_i, B_i]`` (N, 2J), made once."""
        if self._rows is None:
            J, N = self._A.shape
            self._rows = np.empty((N, 2 * J))
            for lo in range(0, N, _STEP_BLOCK):
                part = slice(lo, lo + _STEP_BLOCK)
                self._rows[part, :J] = self._A[:, part].T
                self._rows[part, J:] = self._B[:, part].T
        return self._rows

    def __call__(self):
        """Return ``beta`` and the line steps (each (N,)), computed once."""
        if self._found is None:
            A, B = self._A, self._B
            beta = np.min(B, axis=0)
            line = (np.all((A == 1.0) | ((A == 0.0) & np.isinf(B)), axis=0)
                    & np.isfinite(beta) & (beta >= 0.0))        # the floor at 0 never binds
            self._found = beta, line
        return self._found
