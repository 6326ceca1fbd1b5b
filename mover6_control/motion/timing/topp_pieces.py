"""
The per-interval constraints of the time-optimal timing, and both passes' pieces, compiled.

For every grid interval k of ``motion.time_optimal`` (TOPP-RA, Pham and Pham 2018), with
``x = sdot^2`` and ``u = sddot`` constant on the interval, joint i's acceleration
``q'_i u + q''_i x`` at the interval's start (``x_k``) and at its end (``x_k + 2 delta_k u``)
must lie within ``+-a_i``. Each of these 2n constraints is a line ``|u - slope_j x| <= gamma_j``
(``gamma_j = a / |P_j| > 0``, ``slope_j = -C_j / P_j``, P and C the path derivatives that
multiply u and x); one whose ``P`` vanishes (``|P| <= 1e-12``) bounds x alone (a cap
``a / |C|``) and is a line of ``gamma = inf``, slope 0. From them, per interval:

- the static range: the largest x at which some u meets every line. Some u does if and only if
  every pair i, j has ``|slope_i - slope_j| x <= gamma_i + gamma_j``: the smallest
  ``(gamma_i + gamma_j) / |slope_i - slope_j|`` over the finite pairs (a difference of at most
  1e-15 bounds nothing), and no bound where ``2 min(gamma) / (max(slope) - min(slope))``
  reaches the caps already or the slopes all agree (within 1e-15);
- which lines count: the finite ones, less an end constraint that repeats its start's (on a
  line of the path the derivatives are constant: the same bounds);
- the backward pass's pieces: with ``c_j = slope_j + 1 / (2 delta) > 0``, ``A_j = (1 / (2
  delta)) / c_j`` and ``B_j = gamma_j / c_j``; a line with ``c_j < 0`` caps x at
  ``gamma_j / -c_j``; the cap is the smallest of those and the static range;
- the forward pass's pieces: ``A_j = 1 + 2 delta slope_j``, ``B_j = 2 delta gamma_j``;
  a line that does not count has ``A = 0``, ``B = inf`` in both.

The passes then run the recurrence ``x' = max(0, min(cap, min_j A_j x + B_j))`` over them
(``motion.timing.greedy_scan``). Every interval is a column of its own, so this is one loop over
the intervals with the 2n lines in a few registers: compiled by numba (as array operations over
the grid it took 11 ms of a 1000-waypoint goal's 23; compiled, about 1 ms). Each number is
computed by the operations of the plain array formulation, in the same order, so the results
are the same bit for bit (``test/unit/motion/test_topp_pieces.py`` compares them with it).
Compiled at import from numba's on-disk cache, as ``greedy_scan``.
"""

from __future__ import annotations

import numba
import numpy as np

# Below these a path derivative, or a difference of slopes, counts as zero.
_ZERO_P = 1e-12
_ZERO_SLOPE = 1e-15
# A pair's ratio is computed where ``total <= s_hi * diff * _SLACK`` (else it cannot be below).
_SLACK = 1.0 + 1e-9

_M = 'float64[:, ::1]'
_V = 'float64[::1]'
_PIECES_SIGNATURE = (f'Tuple(({_M}, {_M}, {_V}, {_M}, {_M}))'
                     f'({_M}, {_M}, {_M}, {_M}, {_V}, {_V}, {_V})')


@numba.njit(_PIECES_SIGNATURE, cache=True, nogil=True, error_model='numpy')
def _pieces(dq0, ddq0, dq1, ddq1, delta, a, limit):  # pragma: no cover (compiled)
    """Return ``(back_A, back_B, back_cap, fwd_A, fwd_B)``; ``pieces`` says what they are."""
    N, n = dq0.shape
    m = 2 * n
    back_A, back_B = np.empty((m, N)), np.empty((m, N))
    fwd_A, fwd_B = np.empty((m, N)), np.empty((m, N))
    back_cap = np.empty(N)
    gamma, slope = np.empty(m), np.empty(m)
    keep = np.empty(m, dtype=np.bool_)
    inf = np.inf
    for k in range(N):
        d = delta[k]
        two_d = 2.0 * d
        # The 2n lines, and the cap of those that bound x alone.
        x_cap = inf
        for r in range(m):
            i = r % n
            if r < n:
                P, C = dq0[k, i], ddq0[k, i]
            else:
                P, C = dq1[k, i] + two_d * ddq1[k, i], ddq1[k, i]
            absP = abs(P)
            if absP <= _ZERO_P:
                gamma[r], slope[r] = inf, 0.0
                absC = abs(C)
                if absC > _ZERO_P:
                    x_cap = min(x_cap, a[i] / absC)
            else:
                gamma[r], slope[r] = a[i] / absP, -C / P
        # The lines that count: finite, and an end line not a repeat of its start's.
        for r in range(m):
            keep[r] = gamma[r] < inf
            if r >= n and gamma[r] == gamma[r - n] and slope[r] == slope[r - n]:
                keep[r] = False
        # The static range, below the caps.
        bound = min(x_cap, limit[k])
        s_max, s_min, g_min = slope[0], slope[0], gamma[0]
        for r in range(1, m):
            s_max, s_min = max(s_max, slope[r]), min(s_min, slope[r])
            g_min = min(g_min, gamma[r])
        spread = s_max - s_min
        s_hi = bound
        if spread > _ZERO_SLOPE and not (2.0 * g_min / spread >= bound):
            # The pairs of lines that count (a repeat gives its twin's ratios, and none with
            # it); a ratio is divided out only where it can be below the smallest so far (by
            # a margin far above the roundings: the same minimum). No pair of line p can be
            # where ``(gamma_p + min(gamma)) / (its largest slope difference)`` is not.
            for p in range(m):
                if not keep[p]:
                    continue
                widest = max(s_max - slope[p], slope[p] - s_min)
                if gamma[p] + g_min >= s_hi * widest * _SLACK:
                    continue
                for q in range(p + 1, m):
                    if not keep[q]:
                        continue
                    diff = abs(slope[p] - slope[q])
                    total = gamma[p] + gamma[q]
                    if diff > _ZERO_SLOPE and total <= s_hi * diff * _SLACK:
                        s_hi = min(s_hi, total / diff)
        # Both passes' pieces.
        inv = 1.0 / two_d
        cap = s_hi
        for r in range(m):
            if keep[r]:
                c = slope[r] + inv
                if c > _ZERO_SLOPE:
                    back_A[r, k], back_B[r, k] = inv / c, gamma[r] / c
                else:
                    back_A[r, k], back_B[r, k] = 0.0, inf
                    if c < -_ZERO_SLOPE:
                        cap = min(cap, gamma[r] / -c)
                fwd_A[r, k], fwd_B[r, k] = 1.0 + two_d * slope[r], two_d * gamma[r]
            else:
                back_A[r, k], back_B[r, k] = 0.0, inf
                fwd_A[r, k], fwd_B[r, k] = 0.0, inf
        back_cap[k] = cap
    return back_A, back_B, back_cap, fwd_A, fwd_B


def pieces(ends, delta, a, limit):
    """
    Return the pieces of both passes: backward ``(A, B, cap)``, forward ``(A, B)``.

    ``ends``: the path's first and second derivatives at the start and at the end of every
    interval, each on the interval's own segment (``(dq0, ddq0, dq1, ddq1)``, (N, n) each);
    ``delta`` (N,): the intervals' lengths; ``a`` (n,): the acceleration limits; ``limit``
    (N,): the caps on x the speed limits and the stops give. ``A``, ``B`` are (2n, N), a column
    per interval (``greedy_scan.greedy_scan_columns``), the caps (N,).
    """
    def doubles(v):
        return np.ascontiguousarray(v, dtype=np.float64)
    back_A, back_B, back_cap, fwd_A, fwd_B = _pieces(*(doubles(v) for v in ends), doubles(delta),
                                                     doubles(a), doubles(limit))
    return (back_A, back_B, back_cap), (fwd_A, fwd_B)
