"""
Joint-space trajectories: one sampling interface for every way of timing a joint motion.

``JointTrajectory`` is the base: ``duration`` [s], ``n_joints`` and ``sample(t)`` giving
``(q, qd, qdd)`` [rad, rad/s, rad/s^2] for a scalar ``t`` (each (n,)) or an array ``t`` (m,)
(each (m, n)). ``t`` is clamped to [0, duration], so sampling past the end holds the end.

Builders here:
- ``point_to_point``: a straight joint move under a time law (the Jacobians and trajectories report
  eq. 29-32).
- ``stop_at_each``: the Mover6 report's scheme, one synchronised time-law move per waypoint pair,
  stopping at every waypoint.

The other builders, each a concept of its own on this base: the multi-point splines and blends
(cubic, quintic, B-spline, multi-point trapezoid) in ``motion.spline_trajectories``, ruckig's
jerk-limited move in ``motion.jerk_limited``.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing.time_laws import PolynomialTimeLaw, TrapezoidalTimeLaw
from mover6_control.validation import as_finite_array, as_positive
import numpy as np
from scipy.optimize import minimize_scalar

TimeLaw = PolynomialTimeLaw | TrapezoidalTimeLaw
Limit = float | Sequence[float]

# Sampling density used to find peak rates of a time law.
_PEAK_SAMPLES = 4001


class JointTrajectory:
    """
    Base of every joint trajectory: clamps time and shapes the output.

    Subclasses implement ``_evaluate(t)`` for a float array ``t`` (m,) already clamped to
    [0, duration], returning ``(q, qd, qdd, qddd)`` each (m, n).
    """

    def __init__(self, duration: float, n_joints: int):
        duration = float(duration)
        if not np.isfinite(duration) or duration < 0.0:
            raise InvalidInputError(f'duration must be finite and >= 0, got {duration}')
        self._duration = duration
        self._n_joints = int(n_joints)

    @property
    def duration(self) -> float:
        """Return the duration [s]."""
        return self._duration

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return self._n_joints

    def _times(self, t):
        t_arr = np.asarray(t, dtype=float)
        if t_arr.ndim > 1:
            raise InvalidInputError(f't must be a scalar or 1-D, got shape {t_arr.shape}')
        if not np.all(np.isfinite(t_arr)):
            raise InvalidInputError('t has non-finite values')
        return np.minimum(np.maximum(np.atleast_1d(t_arr), 0.0), self._duration), t_arr.ndim == 0

    def _time(self, t):
        """Return one time ``t`` [s] as a float clamped to [0, duration] (no arrays)."""
        t = float(t)
        if not math.isfinite(t):
            raise InvalidInputError('t has non-finite values')
        return min(max(t, 0.0), self._duration)

    def _evaluate(self, t):
        raise NotImplementedError

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(q, qd, qdd)`` at time(s) ``t`` [s]: (n,) each for a scalar, else (m, n)."""
        times, scalar = self._times(t)
        q, qd, qdd, _ = self._evaluate(times)
        if scalar:
            return q[0], qd[0], qdd[0]
        return q, qd, qdd

    def derivatives(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Return ``(q, qd, qdd, qddd)`` (m, n) each at the times ``t`` (m,) [s] (clamped)."""
        return self._evaluate(self._times(t)[0])

    def sample_jerk(self, t: float | np.ndarray) -> np.ndarray:
        """Return the jerk [rad/s^3] at time(s) ``t``: (n,) for a scalar, else (m, n)."""
        times, scalar = self._times(t)
        jerk = self._evaluate(times)[3]
        return jerk[0] if scalar else jerk

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``(q, qd)`` (n,) each at one time ``t`` [s]: what a control tick needs.

        The same values as ``sample(t)[:2]``; subclasses answer without the array machinery of
        ``sample`` where they can (the controller asks every tick).
        """
        q, qd, _ = self.sample(float(t))
        return q, qd


class TimeLawTrajectory(JointTrajectory):
    """A straight joint move ``q0 -> q1`` in ``duration`` [s] under a time law (eq. 29-32)."""

    def __init__(self, q0: Sequence[float], q1: Sequence[float], duration: float, law: TimeLaw):
        q0 = as_finite_array(q0, (None,), 'q0')
        q1 = as_finite_array(q1, (q0.size,), 'q1')
        super().__init__(as_positive(duration, 'duration'), q0.size)
        self.q0, self.q1, self.law = q0, q1, law

    def _evaluate(self, t):
        T = self._duration
        tau = t / T
        dq = self.q1 - self.q0
        out = [self.q0 + np.outer(self.law.evaluate(tau), dq)]
        for k in (1, 2, 3):
            out.append(np.outer(self.law.evaluate(tau, k), dq) / T ** k)
        return tuple(out)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` (n,) each at one time ``t`` [s] (eq. 29-30)."""
        T = self._duration
        tau = self._time(t) / T
        dq = self.q1 - self.q0
        return (self.q0 + dq * float(self.law.evaluate(tau)),
                dq * float(self.law.evaluate(tau, 1)) / T)


class PiecewiseTrajectory(JointTrajectory):
    """Trajectories played one after another; each starts where the previous ended."""

    def __init__(self, segments: Sequence[JointTrajectory]):
        segments = tuple(segments)
        if not segments:
            raise InvalidInputError('a piecewise trajectory needs at least one segment')
        n = segments[0].n_joints
        if any(s.n_joints != n for s in segments):
            raise InvalidInputError('segments have different numbers of joints')
        self.segments = segments
        self.starts = np.concatenate([[0.0], np.cumsum([s.duration for s in segments])])
        super().__init__(self.starts[-1], n)

    def _evaluate(self, t):
        idx = np.clip(np.searchsorted(self.starts, t, side='right') - 1, 0, len(self.segments) - 1)
        out = [np.empty((t.size, self._n_joints)) for _ in range(4)]
        for i in np.unique(idx):
            mask = idx == i
            seg = self.segments[i]
            local = np.clip(t[mask] - self.starts[i], 0.0, seg.duration)
            for o, v in zip(out, seg.derivatives(local)):
                o[mask] = v
        return tuple(out)


def validate_waypoints(Q: np.ndarray, name: str = 'Q', allow_repeats: bool = False) -> np.ndarray:
    """
    Return waypoints ``Q`` (m, n) [rad] as an array, checking m >= 2 and finiteness.

    Unless ``allow_repeats``, consecutive coincident waypoints are an error (a segment of zero
    length has no direction and no duration).
    """
    Q = as_finite_array(Q, (None, None), name)
    if Q.shape[0] < 2:
        raise InvalidInputError(f'{name} needs at least two waypoints, got {Q.shape[0]}')
    if Q.shape[1] < 1:
        raise InvalidInputError(f'{name} needs at least one joint')
    if not allow_repeats:
        steps = np.abs(np.diff(Q, axis=0)).max(axis=1)
        same = np.flatnonzero(steps < 1e-12)
        if same.size:
            raise InvalidInputError(
                f'{name} has coincident consecutive waypoints at rows {same.tolist()} and '
                f'{(same + 1).tolist()}')
    return Q


@functools.lru_cache(maxsize=64)
def law_peaks(law: TimeLaw) -> tuple[float, float]:
    """
    Return (max |s'|, max |s''|) of a time law over tau in [0, 1].

    Remembered per law (laws are frozen), so timing many moves under one law searches once.

    The largest sample is refined by a bounded search between its neighbours, so a peak that
    falls between samples is not underestimated (a duration fitted to it would break a limit).
    """
    tau = np.linspace(0.0, 1.0, _PEAK_SAMPLES)
    peaks = []
    for k in (1, 2):
        values = np.abs(law.evaluate(tau, k))
        i = int(np.argmax(values))
        lo, hi = tau[max(i - 1, 0)], tau[min(i + 1, tau.size - 1)]
        res = minimize_scalar(lambda x, k=k: -abs(float(law.evaluate(x, k))), bounds=(lo, hi),
                              method='bounded', options={'xatol': 1e-12})
        peaks.append(max(float(values[i]), -float(res.fun)))
    return peaks[0], peaks[1]


def point_to_point(q0: Sequence[float], q1: Sequence[float], law: TimeLaw,
                   duration: Optional[float] = None, v_max: Optional[Limit] = None,
                   a_max: Optional[Limit] = None) -> TimeLawTrajectory:
    """
    Return a straight, synchronised joint move from ``q0`` to ``q1`` under ``law``.

    Give ``duration`` [s], or ``v_max`` [rad/s] (and optionally ``a_max`` [rad/s^2]) per joint:
    then the duration is the shortest for which no joint exceeds its limits (all joints start
    and stop together, the Mover6 report eq. 1-2).
    """
    q0 = as_finite_array(q0, (None,), 'q0')
    q1 = as_finite_array(q1, (q0.size,), 'q1')
    if duration is None:
        if v_max is None:
            raise InvalidInputError('give a duration or v_max')
        dq = np.abs(q1 - q0)
        if dq.max() < 1e-12:
            raise InvalidInputError('q0 and q1 coincide: there is no move to time')
        sd, sdd = law_peaks(law)
        duration = float(np.max(dq * sd / as_positive(v_max, 'v_max', q0.size)))
        if a_max is not None:
            t_acc = np.sqrt(np.max(dq * sdd / as_positive(a_max, 'a_max', q0.size)))
            duration = max(duration, float(t_acc))
    return TimeLawTrajectory(q0, q1, duration, law)


def stop_at_each(Q: np.ndarray, law: TimeLaw | Callable[[float], TimeLaw], v_max: Limit,
                 a_max: Optional[Limit] = None) -> PiecewiseTrajectory:
    """
    Return the Mover6 report's scheme: one synchronised ``law`` move per waypoint pair.

    ``law`` is a time law or a callable ``law(duration)`` (e.g. ``time_laws.trapezoidal``, whose
    blend is a fraction of each segment's duration either way).
    """
    Q = validate_waypoints(Q)
    the_law = law(1.0) if callable(law) and not hasattr(law, 'evaluate') else law
    segs = [point_to_point(Q[k], Q[k + 1], the_law, v_max=v_max, a_max=a_max)
            for k in range(Q.shape[0] - 1)]
    return PiecewiseTrajectory(segs)
