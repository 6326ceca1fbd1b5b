"""
toppra (the library people would pick for path timing) beside ``time_optimal`` on the same input.

Two ways to call it, both with ``ParametrizeConstAccel`` (the same kind of timing as ours:
path acceleration constant per grid interval) and the same joint velocity and acceleration
limits:

- ``same path``: toppra times OUR blended path (``motion.blended_path``, wrapped as a toppra
  geometric path) on OUR grid: identical inputs, so the durations should agree and the run
  times compare the two solvers alone;
- ``spline``: what a user would write: a cubic spline through the same waypoints (chord-length
  parameter) with toppra's default grid. A different path, so a different duration.

Only the benchmarks import this module (toppra is a test/bench requirement, not a product one).
"""

import time

from mover6_control.motion.blended_path import distinct_waypoints
import numpy as np


def _toppra():
    """Import toppra quietly (it logs at INFO on every call otherwise)."""
    import logging
    import toppra
    logging.getLogger('toppra').setLevel(logging.WARNING)
    return toppra


def as_toppra_path(path):
    """Return ``path`` (a ``BlendedPath``) as a toppra ``AbstractGeometricPath``."""
    toppra = _toppra()

    class BlendedToppraPath(toppra.interpolator.AbstractGeometricPath):
        """Our blended path, evaluated by its own code (one-sided at segment starts)."""

        def __call__(self, path_positions, order=0):
            s = np.atleast_1d(np.asarray(path_positions, dtype=float))
            out = path.evaluate(s, path.segment_of(s), (order,))[0]
            return out[0] if np.ndim(path_positions) == 0 else out

        @property
        def dof(self):
            return path.n_joints

        @property
        def path_interval(self):
            return np.array([0.0, path.length])

    return BlendedToppraPath()


def _solve(path, gridpoints, v, a):
    """Return toppra's trajectory of ``path`` under ``v``, ``a`` (n,) on ``gridpoints``."""
    toppra = _toppra()
    constraints = [toppra.constraint.JointVelocityConstraint(np.stack([-v, v], axis=1)),
                   toppra.constraint.JointAccelerationConstraint(np.stack([-a, a], axis=1))]
    algorithm = toppra.algorithm.TOPPRA(constraints, path, gridpoints=gridpoints,
                                        parametrizer='ParametrizeConstAccel')
    return algorithm.compute_trajectory(0.0, 0.0)


def same_path(ours, v, a):
    """
    Return toppra's trajectory on the path and grid of ``ours`` (a ``PathTrajectory``).

    The wrapping of the path is set up outside the timed call; the call is toppra's alone.
    """
    timing = ours.timing
    while not hasattr(timing, 's_grid'):        # a ScaledTiming: the grid is its base's
        timing = timing.base
    wrapped = as_toppra_path(ours.path)
    grid = np.asarray(timing.s_grid)
    return lambda: _solve(wrapped, grid, v, a)


def spline(Q, v, a):
    """Return a call that times a cubic spline through ``Q`` (m, n) with toppra's own grid."""
    toppra = _toppra()
    Q = distinct_waypoints(Q)       # a spline needs distinct ones; ours drops repeats too
    ss = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])

    def build():
        path = toppra.SplineInterpolator(ss, Q)
        return _solve(path, None, v, a)

    return build


def limit_ratios(sample, duration, v, a, dt=1e-3):
    """
    Return the largest ``|qd| / v`` and ``|qdd| / a`` sampled every ``dt`` [s].

    ``sample(t)`` returns ``(qd, qdd)`` (each (m, n)) at times ``t`` (m,).
    """
    t = np.linspace(0.0, duration, max(2, int(np.ceil(duration / dt)) + 1))
    qd, qdd = sample(t)
    return float(np.max(np.abs(qd) / v)), float(np.max(np.abs(qdd) / a))


def toppra_sampler(traj):
    """Return ``sample(t) -> (qd, qdd)`` of a toppra trajectory."""
    return lambda t: (traj(t, 1), traj(t, 2))


def timed(build, repeats):
    """Return the result of ``build`` and the median and shortest of its run times [s]."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = build()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times)), min(times)
