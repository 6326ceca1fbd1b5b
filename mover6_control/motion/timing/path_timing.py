"""
Timings along a ``BlendedPath``: the path position ``s(t)`` and its rates, and the trajectory.

``GridTiming`` is the time-optimal solver's (``motion.time_optimal``): path acceleration
constant per grid interval. ``FilteredTiming`` smooths a timing by a moving average (finite
jerk), ``ScaledTiming`` slows one down uniformly. ``PathTrajectory`` is the joint trajectory
of a path followed with a timing: what the continuous profile plays.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from mover6_control.motion.blended_path import BlendedPath
from mover6_control.motion.timing.trajectories import JointTrajectory
import numpy as np


@dataclass(frozen=True, eq=False)
class GridTiming:
    """
    TOPP's timing: path acceleration ``u_k`` constant on grid interval k.

    On interval k the path position is ``s_k + sdot_k tau + u_k tau^2 / 2`` for ``tau`` in
    [0, t_{k+1} - t_k]; before the start it rests at 0, after the end at ``s_grid[-1]``.
    """

    s_grid: np.ndarray      # (N + 1,) [rad]
    sd: np.ndarray          # (N + 1,) path speed at the grid points [rad/s]
    u: np.ndarray           # (N,) path acceleration per interval [rad/s^2]
    t_grid: np.ndarray      # (N + 1,) [s]

    @cached_property
    def _cum(self) -> np.ndarray:
        """
        Return the integral of s at the grid times (N + 1,), computed on first use.

        Only the smoothing (``FilteredTiming``, jerk limits) asks for it: a timing that is
        not smoothed does not pay for it.
        """
        dt = np.diff(self.t_grid)
        pieces = self.s_grid[:-1] * dt + self.sd[:-1] * dt ** 2 / 2 + self.u * dt ** 3 / 6
        return np.concatenate([[0.0], np.cumsum(pieces)])

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return float(self.t_grid[-1])

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        # np.minimum / np.maximum rather than np.clip: several times faster on the one-element
        # arrays of a control tick.
        t = np.asarray(t, dtype=float)
        k = np.minimum(np.maximum(np.searchsorted(self.t_grid, t, side='right') - 1, 0),
                       self.u.size - 1)
        t0 = self.t_grid[k]
        tau = np.minimum(np.maximum(t - t0, 0.0), self.t_grid[k + 1] - t0)
        u = self.u[k]
        s = np.minimum(np.maximum(self.s_grid[k] + self.sd[k] * tau + 0.5 * u * tau ** 2,
                                  self.s_grid[k]), self.s_grid[k + 1])
        sd = np.maximum(self.sd[k] + u * tau, 0.0)
        sdd = u.copy()
        before, after = t < 0.0, t > self.duration
        s[before], s[after] = 0.0, self.s_grid[-1]
        sd[before | after] = 0.0
        sdd[before | after] = 0.0
        return s, sd, sdd, np.zeros_like(s)

    def integral(self, t: np.ndarray) -> np.ndarray:
        """Return the integral of ``s`` from 0 to ``t`` (m,) [rad s]; s holds its end after."""
        t = np.asarray(t, dtype=float)
        tc = np.minimum(np.maximum(t, 0.0), self.duration)
        k = np.minimum(np.searchsorted(self.t_grid, tc, side='right') - 1, self.u.size - 1)
        tau = tc - self.t_grid[k]
        part = self.s_grid[k] * tau + self.sd[k] * tau ** 2 / 2 + self.u[k] * tau ** 3 / 6
        return self._cum[k] + part + self.s_grid[-1] * np.maximum(t - self.duration, 0.0)

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the first time [s] at which the path position reaches ``s`` (m,)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.s_grid[-1])
        k = np.clip(np.searchsorted(self.s_grid, s, side='right') - 1, 0, self.u.size - 1)
        ds = s - self.s_grid[k]
        v0, u = self.sd[k], self.u[k]
        # Solve ds = v0 tau + u tau^2 / 2 for the smallest tau >= 0 (stable form).
        disc = np.sqrt(np.maximum(v0 ** 2 + 2.0 * u * ds, 0.0))
        with np.errstate(divide='ignore', invalid='ignore'):
            tau = np.where(v0 + disc > 0.0, 2.0 * ds / (v0 + disc), 0.0)
        return self.t_grid[k] + np.minimum(tau, self.t_grid[k + 1] - self.t_grid[k])


@dataclass(frozen=True, eq=False)
class FilteredTiming:
    """
    A timing smoothed by a moving average over ``window`` [s]: jerk becomes finite.

    ``s_f(t)`` is the mean of ``s`` over [t - window, t], so ``sdddot_f`` is the difference of
    ``sddot`` across the window divided by it. ``s_f`` is a re-timing of the same path: the
    geometry is untouched. The motion lasts ``window`` longer.
    """

    base: GridTiming
    window: float           # [s]

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self.base.duration + self.window

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        t = np.asarray(t, dtype=float)
        w = self.window
        now = self.base.profile(t)
        then = self.base.profile(t - w)
        s = (self.base.integral(t) - self.base.integral(t - w)) / w
        return (np.minimum(np.maximum(s, 0.0), self.base.s_grid[-1]),) + tuple(
            (a - b) / w for a, b in zip(now[:3], then[:3]))

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the time [s] at which the smoothed path position reaches ``s`` (m,)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        t_lo = self.base.time_at(s)               # s_f lags s: s_f(t) = s no earlier ...
        t_hi = np.minimum(t_lo + self.window, self.duration)   # ... and no later than this
        for _ in range(60):
            mid = 0.5 * (t_lo + t_hi)
            below = self.profile(mid)[0] < s
            t_lo, t_hi = np.where(below, mid, t_lo), np.where(below, t_hi, mid)
        return t_hi


@dataclass(frozen=True, eq=False)
class ScaledTiming:
    """A timing slowed down uniformly by ``factor`` >= 1: rates scale by 1 / factor^k."""

    base: object
    factor: float

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self.base.duration * self.factor

    def profile(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``s, sdot, sddot, sdddot`` (each (m,)) at times ``t`` (m,) [s]."""
        out = self.base.profile(np.asarray(t, dtype=float) / self.factor)
        return tuple(v / self.factor ** k for k, v in enumerate(out))

    def time_at(self, s: np.ndarray) -> np.ndarray:
        """Return the time [s] at which the path position reaches ``s`` (m,)."""
        return self.base.time_at(s) * self.factor


class PathTrajectory(JointTrajectory):
    """A ``BlendedPath`` followed with a timing ``s(t)`` (``GridTiming`` or a smoothing of it)."""

    def __init__(self, path: BlendedPath, timing: GridTiming | FilteredTiming | ScaledTiming):
        super().__init__(timing.duration, path.n_joints)
        self.path = path
        self.timing = timing

    def derivatives(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``q, qd, qdd, qddd`` (each (m, n)) at times ``t`` (m,) in [0, duration] [s]."""
        return self._evaluate(np.asarray(t, dtype=float))

    def _evaluate(self, t):
        s, sd, sdd, sddd = self.timing.profile(t)
        q, dq, ddq, dddq = self.path.evaluate(s, self.path.segment_of(s))
        sd, sdd, sddd = sd[:, None], sdd[:, None], sddd[:, None]
        qd = dq * sd
        qdd = dq * sdd + ddq * sd ** 2
        qddd = dq * sddd + 3.0 * ddq * sd * sdd + dddq * sd ** 3
        return q, qd, qdd, qddd

    @property
    def waypoint_times(self) -> np.ndarray:
        """Return the time [s] at which the arm passes (closest to) each waypoint (m,)."""
        return self.timing.time_at(np.asarray(self.path.waypoint_s))
