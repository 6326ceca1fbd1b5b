"""
Which arc intervals of a time-optimal timing keep the limits between their grid points, compiled.

The timing (``motion.time_optimal``) enforces the speed and acceleration limits at the grid
points. On a line of the path that is enough; on a corner arc the tangent turns inside an
interval. On an arc of radius r each joint's path derivative ``q'`` is a sinusoid of amplitude
``R = sqrt(x_i^2 + y_i^2) <= 1`` in the angle ``phi = s / r``, so inside an interval spanning
``dphi`` it exceeds the larger of its end values by at most ``bump = R dphi^2 / 8``; the speed
``sdot`` lies between its end values (u is constant). The joint's acceleration ``g(s) = u q' +
x q''`` (``x = sdot^2``, ``dx / ds = 2 u``) has the second derivative ``5 u q''' + x q''''``,
at most ``R (5 |u| / r^2 + x / r^3)``, so it exceeds the larger of its end values by at most
``bump (5 |u| + x / r)``. An interval whose bounds are within the limits needs no samples
(``time_optimal._within_limits`` samples the others).

One loop over the arc intervals, each joint's bounds in registers: compiled by numba (as array
operations, gathering each interval's values into (m, n) temporaries, it took 4 ms of a
1000-waypoint goal's timing; compiled, about 0.2 ms). Each bound is computed by the operations
of the array formulation in the same order (``test/unit/motion/test_arc_bounds.py`` compares
them), so the same intervals pass. Compiled at import from numba's cache, as ``greedy_scan``.
"""

from __future__ import annotations

import numba
import numpy as np

# The arc vectors and radii, the grid timing, the ends, the intervals and their arcs, v and a.
_ARC_SIGNATURE = 'boolean[::1]({})'.format(', '.join(
    ['float64[:, ::1]'] * 2 + ['float64[::1]'] * 4 + ['float64[:, ::1]'] * 4 + ['int64[::1]'] * 2
    + ['float64[::1]'] * 2))


@numba.njit(_ARC_SIGNATURE, cache=True, nogil=True, error_model='numpy')
def _within(x, y, radius, s_grid, sd, u, dq0, ddq0, dq1, ddq1, segment, k, v,
            a):  # pragma: no cover (compiled)
    """Return ``intervals_within``'s answer; the arguments are its, as plain arrays."""
    m, n = k.size, dq0.shape[1]
    out = np.empty(m, dtype=np.bool_)
    for p in range(m):
        i, j = k[p], segment[p]
        r = radius[j]
        w = (s_grid[i + 1] - s_grid[i]) / r
        w2 = w * w
        sd0, sd1, up = sd[i], sd[i + 1], u[i]
        top = max(sd0, sd1)
        x_top = top * top
        x0, x1 = sd0 * sd0, sd1 * sd1
        grow = 5.0 * abs(up) + x_top / r
        ok = True
        for c in range(n):
            amplitude = np.sqrt(x[j, c] * x[j, c] + y[j, c] * y[j, c])
            bump = amplitude * w2 / 8.0
            speed = (max(abs(dq0[i, c]), abs(dq1[i, c])) + bump) * top
            accel = (max(abs(up * dq0[i, c] + x0 * ddq0[i, c]),
                         abs(up * dq1[i, c] + x1 * ddq1[i, c])) + bump * grow)
            if not (speed <= v[c] and accel <= a[c]):
                ok = False
                break
        out[p] = ok
    return out


def intervals_within(arcs, timing, segment, k, ends, v, a):
    """
    Return which arc intervals ``k`` (m,) keep the limits ``v``, ``a`` (n,) throughout (bool).

    ``arcs``: the path's arc vectors ``(x, y, radius)`` by segment (``BlendedPath.arc_rows``);
    ``timing``: the grid timing (``s_grid``, ``sd``, ``u``); ``segment`` (m,): each
    interval's arc; ``ends``: the path's first and second derivatives at the start and at the
    end of every grid interval (``(dq0, ddq0, dq1, ddq1)``, (N, n) each).
    """
    def doubles(values):
        return np.ascontiguousarray(values, dtype=np.float64)

    def indices(values):
        return np.ascontiguousarray(values, dtype=np.int64)
    x, y, radius = arcs
    return _within(doubles(x), doubles(y), doubles(radius), doubles(timing.s_grid),
                   doubles(timing.sd), doubles(timing.u), *(doubles(d) for d in ends),
                   indices(segment), indices(k), doubles(v), doubles(a))
