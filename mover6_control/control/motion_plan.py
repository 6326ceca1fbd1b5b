"""
A ``MotionPlan``: the reference of one motion, segments in a row, and its segment builders.

A plan's ``sample(t) -> (q_ref, qd_ref)`` covers ``[0, duration]`` [s]; each segment is one
piece of reference sampled at ``tau`` in ``[0, duration]``. The builders make the segments of
the stop-at-each profiles (``synchronised_segment``, ``trapezoid_segment``,
``time_law_segment``) and the deceleration to rest every profile starts with when the arm moves
(``stop_segment``; ``plan_stop``). Every segment respects the joints' velocity limits by one
common factor that stretches time, so the direction of motion and the synchronised arrival are
kept.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Sequence

from mover6_control.control.commands import common_scale
from mover6_control.motion.timing.time_laws import trapezoidal
from mover6_control.motion.timing.trajectories import (JointTrajectory, point_to_point,
                                                       TimeLawTrajectory)
from mover6_control.validation import as_positive
import numpy as np


# --- segments: one piece of reference, sampled at tau in [0, duration] ----------------------

@dataclass(frozen=True, eq=False)
class ConstantVelocitySegment:
    """Straight line in joint space at constant velocity (the Mover6 report eq. 2)."""

    q0: np.ndarray
    q1: np.ndarray
    duration: float

    def sample(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` at ``tau`` [s] into the segment."""
        if self.duration <= 0.0:
            return self.q1, np.zeros_like(self.q1)
        qd = (self.q1 - self.q0) / self.duration
        return self.q0 + qd * tau, qd

    def positions(self, tau: np.ndarray) -> np.ndarray:
        """Return ``q`` (m, n) at ``tau`` (m,) [s], as ``sample`` each."""
        if self.duration <= 0.0:
            return np.broadcast_to(self.q1, (tau.size, self.q1.size))
        return self.q0 + (self.q1 - self.q0) / self.duration * tau[:, None]


@dataclass(frozen=True, eq=False)
class DecelerationSegment:
    """Linear ramp of the velocity from ``qd0`` to zero over ``duration`` (direction kept)."""

    q0: np.ndarray
    qd0: np.ndarray
    duration: float

    @property
    def q1(self) -> np.ndarray:
        """Return the position [rad] where the ramp comes to rest."""
        return self.q0 + self.qd0 * self.duration / 2.0

    def sample(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` at ``tau`` [s]."""
        if tau >= self.duration:
            return self.q1, np.zeros_like(self.q0)
        return (self.q0 + self.qd0 * (tau - tau * tau / (2.0 * self.duration)),
                self.qd0 * (1.0 - tau / self.duration))

    def positions(self, tau: np.ndarray) -> np.ndarray:
        """Return ``q`` (m, n) at ``tau`` (m,) [s], as ``sample`` each."""
        ramp = (tau - tau * tau / (2.0 * self.duration))[:, None]
        return np.where((tau >= self.duration)[:, None], self.q1, self.q0 + self.qd0 * ramp)


@dataclass(frozen=True, eq=False)
class TrajectorySegment:
    """A ``motion.trajectories.JointTrajectory`` played until ``duration``, then held at ``q1``."""

    trajectory: JointTrajectory
    duration: float
    q1: np.ndarray

    def sample(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` at ``tau`` [s]."""
        if tau >= self.duration:
            return self.q1, np.zeros_like(self.q1)
        return self.trajectory.state(tau)

    def positions(self, tau: np.ndarray) -> np.ndarray:
        """Return ``q`` (m, n) at ``tau`` (m,) [s], as ``sample`` each: one trajectory call."""
        out = np.empty((tau.size, self.q1.size))
        moving = tau < self.duration
        out[moving] = self.trajectory.sample(tau[moving])[0]
        out[~moving] = self.q1
        return out


# --- the plan: segments in a row ------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class MotionPlan:
    """
    A reference made of segments in a row, and when each waypoint is reached.

    ``waypoints`` (N, n) [rad] are the demanded positions; ``waypoint_times`` (N,) [s] the times
    at which the reference reaches each. ``sample(t)`` holds the last waypoint after the end.
    """

    segments: tuple
    waypoints: np.ndarray
    waypoint_times: np.ndarray

    def __post_init__(self):
        """Compute the start time of each segment."""
        starts, t = [], 0.0
        for seg in self.segments:
            starts.append(t)
            t += seg.duration
        object.__setattr__(self, '_starts', starts)
        object.__setattr__(self, '_duration', t)

    @property
    def duration(self) -> float:
        """Return the total duration [s]."""
        return self._duration

    @property
    def q_goal(self) -> np.ndarray:
        """Return the last waypoint (n,) [rad]."""
        return self.waypoints[-1]

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q_ref, qd_ref)`` (n,) [rad], [rad/s] at ``t`` [s] after the start."""
        if t >= self._duration or not self.segments:
            return self.q_goal.copy(), np.zeros_like(self.q_goal)
        i = max(0, bisect.bisect_right(self._starts, t) - 1)
        return self.segments[i].sample(max(0.0, t - self._starts[i]))

    def positions(self, times: np.ndarray) -> np.ndarray:
        """
        Return ``q_ref`` (m, n) [rad] at ``times`` (m,) [s], increasing: ``sample(t)[0]`` each.

        Each segment takes its times in one call (``positions`` of the segment): the collision
        guard's samples of a large demand's time-optimal plan cost one trajectory call, not one
        per sample.
        """
        times = np.asarray(times, dtype=float)
        out = np.empty((times.size, self.q_goal.shape[0]))
        after = times >= self._duration
        out[after] = self.q_goal
        if not self.segments:
            out[:] = self.q_goal
            return out
        inside = np.flatnonzero(~after)
        index = np.maximum(np.searchsorted(self._starts, times[inside], side='right') - 1, 0)
        # ``times`` increase, so each segment's rows are one run of ``inside``.
        segments, first, count = np.unique(index, return_index=True, return_counts=True)
        for i, k, c in zip(segments.tolist(), first.tolist(), count.tolist()):
            rows = inside[k:k + c]
            out[rows] = self.segments[i].positions(np.maximum(0.0, times[rows] - self._starts[i]))
        return out

    def waypoints_reached(self, t: float) -> int:
        """Return how many waypoints the reference has reached at ``t`` [s] (0..N)."""
        return int(np.searchsorted(self.waypoint_times, t, side='right'))


# --- segment builders ----------------------------------------------------------------------

def stop_segment(q_start: np.ndarray, qd_start: np.ndarray,
                 a_max: float | Sequence[float]) -> DecelerationSegment:
    """
    Return the ramp from ``qd_start`` (n,) [rad/s] to rest within ``a_max`` [rad/s^2].

    One common duration ``max_i |qd_i| / a_max_i`` for all joints, so the direction is kept.
    """
    q_start = np.asarray(q_start, dtype=float)
    qd_start = np.asarray(qd_start, dtype=float)
    a_max = as_positive(a_max, 'a_max', q_start.shape[0])
    duration = float(np.max(np.abs(qd_start) / a_max))
    return DecelerationSegment(q_start, qd_start, duration)


def plan_stop(q_start: np.ndarray, qd_start: np.ndarray,
              a_max: float | Sequence[float]) -> MotionPlan:
    """Return a ``MotionPlan`` that brings the arm from ``qd_start`` to rest within ``a_max``."""
    seg = stop_segment(q_start, qd_start, a_max)
    return MotionPlan((seg,), seg.q1[None, :], np.array([seg.duration]))


def synchronised_segment(q0: np.ndarray, q1: np.ndarray, lambda_max: float,
                         velocity_limits: np.ndarray) -> ConstantVelocitySegment:
    """
    Return the constant-velocity segment of the Mover6 report eq. 1-2 from ``q0`` to ``q1``.

    ``t_max = max |q1 - q0| / lambda_max`` (eq. 1), stretched by one common factor when a
    joint's speed ``(q1 - q0) / t_max`` (eq. 2) would exceed its velocity limit.
    """
    delta = q1 - q0
    t_max = float(np.max(np.abs(delta))) / lambda_max
    if t_max > 0.0:
        t_max *= common_scale(delta / t_max, velocity_limits)
    return ConstantVelocitySegment(q0, q1, t_max)


def trapezoid_segment(q0: np.ndarray, q1: np.ndarray, t_max: float, t_blend: float,
                      velocity_limits: np.ndarray) -> ConstantVelocitySegment | TrajectorySegment:
    """
    Return the trapezoid of the Mover6 report eq. 16-18 from ``q0`` to ``q1`` over ``t_max`` [s].

    Every joint follows ``time_laws.trapezoidal(t_max, t_blend)``, so its plateau velocity is
    ``V_max = (q1 - q0) / (t_max - t_blend)`` (eq. 16). When a joint's ``V_max`` exceeds its
    velocity limit, ``t_max`` and ``t_blend`` are stretched by one common factor (the shape and
    synchronised arrival are kept). A move of zero length takes no time.
    """
    delta = q1 - q0
    if not np.any(delta):
        return ConstantVelocitySegment(q0, q1, 0.0)
    scale = common_scale(delta / (t_max - t_blend), velocity_limits)
    law = trapezoidal(t_max * scale, t_blend * scale)
    return TrajectorySegment(TimeLawTrajectory(q0, q1, t_max * scale, law), t_max * scale,
                             q1.copy())


def time_law_segment(q0: np.ndarray, q1: np.ndarray, law, velocity_limits: np.ndarray,
                     a_max: float | Sequence[float]
                     ) -> ConstantVelocitySegment | TrajectorySegment:
    """
    Return a synchronised rest-to-rest move ``q0 -> q1`` under a time ``law``, within the limits.

    The duration is the shortest for which no joint exceeds its velocity limit nor ``a_max``
    (the law's peak ``s'`` and ``s''``, ``trajectories.point_to_point``). A move of zero length
    takes no time.
    """
    if not np.any(np.abs(q1 - q0) > 1e-12):
        return ConstantVelocitySegment(q0, q1, 0.0)
    move = point_to_point(q0, q1, law, v_max=velocity_limits, a_max=a_max)
    return TrajectorySegment(move, move.duration, q1.copy())
