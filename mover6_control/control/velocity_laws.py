"""
The controller's velocity laws behind one small interface, plus closed loop and limits.

A law turns the start state and the waypoints (N, n) [rad] into a ``MotionPlan``: a reference
``sample(t) -> (q_ref, qd_ref)`` over ``[0, duration]`` [s]. The laws (``PROFILES``):

- ``synchronised``: the Mover6 report eq. 1-2. Per waypoint, the joint with the furthest to go
  moves at ``lambda_max`` and sets ``t_max``; every joint moves at ``(q_k - q_{k-1}) / t_max`` so
  all arrive together; the arm stops at each waypoint.
- ``trapezoidal``: the Mover6 report eq. 16-18 per waypoint: ``V_max = |dq| / (t_max - t_blend)``,
  ramps of ``t_blend`` (default ``t_max / 4``); stops at each waypoint. The profile is the one
  of ``motion.time_laws.trapezoidal``.
- ``jerk_limited``: ruckig, rest to rest per waypoint, within velocity, ``a_max`` and ``j_max``
  (``motion.trajectories.ruckig_trajectory``).
- ``continuous``: the motion library's time-parameterised trajectory through all waypoints,
  without stopping at each (``motion.timing.time_parameterize``).
- ``cubic``, ``quintic`` (3-4-5), ``septic`` (4-5-6-7), ``sharp_trapezoid``: the time laws of
  the Jacobians and trajectories report, one synchronised move per waypoint, stopping at each,
  each move the shortest within the velocity limits and ``a_max`` (``time_law_segment``).
- ``cubic_spline``, ``quintic_spline``, ``bspline``, ``multi_trapezoid``: the multi-point
  trajectories of the same report through (or, B-spline and blends, near) all waypoints without
  stopping, fitted to the velocity limits and ``a_max`` by one common time factor.

Every law respects the joints' velocity limits by one common factor that stretches time (so the
direction of motion and the synchronised arrival are kept). A plan started while the arm moves
begins from the present commanded velocity: ruckig and the continuous law start from it directly,
every other law first decelerates from it (common factor, ``a_max``). So replacing a
motion never makes the command jump.

The command of every tick is ``closed_loop_command``: ``qd_ref + kp (q_ref - q)`` (the closed-loop
correction on the measured position), scaled by one common factor into the velocity limits,
then ``guard_position_limits`` so no joint is driven further past a limit.

For a driver that reads JointJog as fractions of the maximum speed and moves whole encoder ticks
per cycle (the Mover6's vendor driver), ``dead_zone_command`` lifts commands too small to move a
tick up to ``min_jog_speed`` while the error exceeds half a tick (see ``controller_core``).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
# Imported with this module, not lazily in the first continuous demand's callback: that import
# (scipy.interpolate; 0.1 s idle, far longer on a loaded machine) held up the controller.
from mover6_control.motion import time_laws, timing
from mover6_control.motion.time_laws import trapezoid_times, trapezoidal
from mover6_control.motion.trajectories import (bspline_trajectory, cubic_trajectory,
                                                JointTrajectory, multipoint_trapezoidal,
                                                point_to_point, quintic_trajectory,
                                                ruckig_trajectory, TimeLawTrajectory)
from mover6_control.validation import as_positive
import numpy as np

# Per waypoint, stopping at each: the time laws of the Jacobians and trajectories report, each
# move as short as the velocity limits and a_max allow (``trajectories.point_to_point``).
STOP_AT_EACH_LAWS = {'cubic': time_laws.cubic, 'quintic': time_laws.quintic,
                     'septic': time_laws.septic, 'sharp_trapezoid': time_laws.sharp_trapezoid}
# Through every waypoint without stopping: the multi-point trajectories of the same report,
# fitted to the velocity limits and a_max by one common time factor.
THROUGH_ALL_TRAJECTORIES = {
    'cubic_spline': lambda Q, v, a: cubic_trajectory(Q, v_max=v, a_max=a),
    'quintic_spline': lambda Q, v, a: quintic_trajectory(Q, v_max=v, a_max=a),
    'bspline': lambda Q, v, a: bspline_trajectory(Q, v_max=v, a_max=a),
    'multi_trapezoid': lambda Q, v, a: multipoint_trapezoidal(Q, v, a),
}
PROFILES = ('synchronised', 'trapezoidal', 'jerk_limited', 'continuous',
            'cubic', 'quintic', 'septic', 'sharp_trapezoid',
            'cubic_spline', 'quintic_spline', 'bspline', 'multi_trapezoid')
# The families the report's figure compares (``tools.plots.profile_comparison``).
PROFILE_FAMILIES = {
    'stop at each waypoint': ('synchronised', 'trapezoidal', 'jerk_limited', 'cubic', 'quintic',
                              'septic', 'sharp_trapezoid'),
    'through all waypoints': ('continuous', 'cubic_spline', 'quintic_spline', 'bspline',
                              'multi_trapezoid'),
}
JOG_UNITS = ('rad_per_s', 'fraction_of_max')


@dataclass(frozen=True)
class LawConfig:
    """
    Which law and its parameters.

    ``lambda_max`` [rad/s] (synchronised), ``t_max`` [s] and ``t_blend`` [s] (trapezoidal; 0 or
    None means ``t_max / 4``), ``a_max`` [rad/s^2] and ``j_max`` [rad/s^3] (jerk-limited,
    continuous, and the deceleration of every law when stopping or replacing a motion).
    """

    profile: str = 'continuous'
    lambda_max: float = 0.5
    t_max: float = 1.0
    t_blend: float = 0.0
    a_max: float = 1.0
    j_max: float = 5.0

    def __post_init__(self):
        """Check the profile name and that every parameter is a positive number."""
        if self.profile not in PROFILES:
            raise InvalidInputError(f'profile must be one of {PROFILES}, got "{self.profile}"')
        for name in ('lambda_max', 't_max', 'a_max', 'j_max'):
            as_positive(getattr(self, name), name)
        trapezoid_times(self.t_max, self.blend)

    @property
    def blend(self) -> float:
        """Return ``t_blend`` [s], defaulting to ``t_max / 4`` (the Mover6 report)."""
        return self.t_max / 4.0 if self.t_blend in (None, 0.0) else float(self.t_blend)


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

    def waypoints_reached(self, t: float) -> int:
        """Return how many waypoints the reference has reached at ``t`` [s] (0..N)."""
        return int(np.searchsorted(self.waypoint_times, t, side='right'))


# --- limits ---------------------------------------------------------------------------------

def common_scale(qd: np.ndarray, velocity_limits: np.ndarray) -> float:
    """Return the factor >= 1 by which ``qd`` (n,) must be divided to respect the limits."""
    ratio = np.max(np.abs(qd) / velocity_limits)
    return max(1.0, float(ratio))


def scale_to_limits(qd: np.ndarray, velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return ``qd`` (n,) [rad/s] divided by one common factor so every ``|qd_i| <= limit_i``.

    The direction of motion in joint space is kept (unlike clipping each joint).
    """
    return qd / common_scale(qd, velocity_limits)


def guard_position_limits(qd: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                          dt: float) -> np.ndarray:
    """
    Return ``qd`` (n,) with no joint driven further past a limit, nor across it within ``dt``.

    A joint at or beyond a limit may only move back inside; a joint inside may move at most to
    the limit in one tick of ``dt`` [s]. This acts per joint: safety before direction.
    """
    qd = np.array(qd, dtype=float)
    room_up = np.maximum(upper - q, 0.0) / dt
    room_down = np.minimum(lower - q, 0.0) / dt
    return np.clip(qd, room_down, room_up)


def closed_loop_command(q_ref: np.ndarray, qd_ref: np.ndarray, q: np.ndarray, gain: float,
                        velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return the velocity command (n,) [rad/s]: feedforward plus correction, within the limits.

    ``qd = qd_ref + gain (q_ref - q)`` with ``gain`` [1/s] on the measured ``q`` [rad], then one
    common factor so no joint exceeds ``velocity_limits`` (n,) [rad/s].
    """
    return scale_to_limits(qd_ref + gain * (q_ref - q), velocity_limits)


def to_jog_units(qd: np.ndarray, velocity_limits: np.ndarray, units: str = 'rad_per_s',
                 speed_override: float = 0.25) -> np.ndarray:
    """
    Return the JointJog velocities for ``qd`` (n,) [rad/s] in the driver's ``units``.

    ``rad_per_s``: unchanged (ROS standard). ``fraction_of_max``: the vendor driver's reading,
    where it moves at ``value * velocity_limit * speed_override``; clipped to [-1, 1].
    """
    if units == 'rad_per_s':
        return np.asarray(qd, dtype=float)
    if units == 'fraction_of_max':
        return np.clip(np.asarray(qd) / (np.asarray(velocity_limits) * speed_override), -1.0, 1.0)
    raise InvalidInputError(f'jog_units must be one of {JOG_UNITS}, got "{units}"')


def driver_velocity_limits(velocity_limits: Sequence[float], units: str = 'rad_per_s',
                           speed_override: float = 0.25) -> np.ndarray:
    """Return the speeds (n,) [rad/s] the driver can reach in ``units`` (override applied)."""
    velocity_limits = np.asarray(velocity_limits, dtype=float)
    if units == 'fraction_of_max':
        return velocity_limits * speed_override
    return velocity_limits


# --- drivers that move whole encoder ticks per cycle (fraction_of_max) ----------------------

# The Mover6's tick sizes and driver cycle are arm facts: mover6_control.arm.MOVER6_TICK_SIZE
# and MOVER6_DRIVER_CYCLE.
# The smallest command is this much above one tick per cycle, so that rounding in the driver
# cannot lose the tick (and below two ticks per cycle, so it cannot add one).
TICK_MARGIN = 1.05


def min_jog_speed(tick_size: Sequence[float], driver_cycle: float) -> np.ndarray:
    """
    Return the smallest speed (n,) [rad/s] that moves each joint one whole tick per cycle.

    ``tick_size`` (n,) [rad] is one encoder tick, ``driver_cycle`` [s] the driver's cycle; the
    result is ``TICK_MARGIN * tick_size / driver_cycle`` (Mover6 J5/J6: 0.129 rad/s, 7.4 deg/s).
    A driver that moves whole ticks per cycle does not move a joint commanded less.
    """
    tick_size = as_positive(tick_size, 'tick_size', np.size(tick_size))
    return TICK_MARGIN * tick_size / as_positive(driver_cycle, 'driver_cycle')


def dead_zone_command(qd: np.ndarray, error: np.ndarray, tick_size: np.ndarray,
                      min_speed: np.ndarray,
                      may_move: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return ``(qd, in_dead_zone)``: the command (n,) [rad/s] for a driver that moves whole ticks.

    Joints commanded at least ``min_speed`` (n,) [rad/s] keep ``qd``: the driver resolves them.
    Below it (``in_dead_zone``) the driver would not move the joint at all, so a joint whose
    position ``error`` (n,) [rad] exceeds half a tick (``tick_size`` (n,) [rad]) gets exactly
    ``min_speed`` towards the error when ``may_move`` (n,) bool allows it, and zero otherwise;
    a joint within half a tick (the nearest tick: nothing better exists) gets zero.
    """
    qd = np.asarray(qd, dtype=float)
    error = np.asarray(error, dtype=float)
    dead = np.abs(qd) < min_speed
    move = dead & np.asarray(may_move, dtype=bool) & (np.abs(error) > 0.5 * np.asarray(tick_size))
    out = np.where(dead, np.where(move, np.sign(error) * min_speed, 0.0), qd)
    return out, dead


def tick_pulse_command(error: np.ndarray, tick_size: np.ndarray, driver_cycle: float,
                       velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return the speeds (n,) [rad/s] that move each joint whole ticks towards ``error`` in a cycle.

    For a driver that moves ``trunc(speed * driver_cycle / tick)`` ticks per cycle: each joint
    gets ``k = round(error / tick_size)`` ticks (``error`` (n,) [rad], ``tick_size`` (n,)
    [rad]), at most what ``velocity_limits`` (n,) [rad/s] allow in one ``driver_cycle`` [s],
    commanded as ``(|k| + TICK_MARGIN - 1) tick / cycle`` so the truncation gives exactly ``k``.
    Held for one driver cycle it closes the error to the nearest tick in one step (zero for a
    joint within half a tick).
    """
    tick_size = np.asarray(tick_size, dtype=float)
    k_max = np.maximum(np.floor(np.asarray(velocity_limits) * driver_cycle / tick_size
                                - (TICK_MARGIN - 1.0)), 1.0)
    k = np.minimum(np.abs(np.round(np.asarray(error, dtype=float) / tick_size)), k_max)
    return np.where(k > 0.0, np.sign(error) * (k + TICK_MARGIN - 1.0) * tick_size / driver_cycle,
                    0.0)


# --- laws -----------------------------------------------------------------------------------

def _check_inputs(q_start, waypoints, velocity_limits, qd_start):
    q_start = np.asarray(q_start, dtype=float)
    n = q_start.shape[0] if q_start.ndim == 1 else -1
    waypoints = np.asarray(waypoints, dtype=float)
    if q_start.ndim != 1 or waypoints.ndim != 2 or waypoints.shape[1] != n or not len(waypoints):
        raise InvalidInputError(
            f'need q_start (n,) and waypoints (N, n), got {q_start.shape} and {waypoints.shape}')
    if not (np.all(np.isfinite(q_start)) and np.all(np.isfinite(waypoints))):
        raise InvalidInputError('q_start and waypoints must be finite')
    qd_start = np.zeros(n) if qd_start is None else np.asarray(qd_start, dtype=float)
    if qd_start.shape != (n,) or not np.all(np.isfinite(qd_start)):
        raise InvalidInputError(f'qd_start must be a finite ({n},) array')
    return q_start, waypoints, as_positive(velocity_limits, 'velocity_limits', n), qd_start


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


def _per_waypoint(q_start, waypoints, make, first=()):
    segments, times, q0 = list(first), [], q_start
    t = sum(s.duration for s in segments)
    if len(waypoints) > 1 and np.max(np.abs(waypoints[0] - q_start)) <= MERGE_STEP:
        # The planner's first waypoint is where the arm was: the measured start lies a fraction
        # of a milliradian from it. A stop-at-each law would spend a whole move (the report's
        # trapezoid: t_max) on that; start from the waypoint instead (closed loop absorbs it).
        times.append(t)
        q0, waypoints = waypoints[0], waypoints[1:]
    for q1 in waypoints:
        seg = make(q0, q1)
        segments.append(seg)
        t += seg.duration
        times.append(t)
        q0 = q1
    return MotionPlan(tuple(segments), waypoints, np.array(times))


def _continuous_plan(q_start, waypoints, velocity_limits, config, qd_start):
    n = q_start.shape[0]
    a_max = as_positive(config.a_max, 'a_max', n)
    first = ()
    path = np.vstack([q_start, waypoints])
    keep = np.concatenate([[True], np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)])
    if keep.sum() < 2:
        return MotionPlan((), waypoints, np.zeros(len(waypoints)))
    trajectory = timing.time_parameterize(path[keep], velocity_limits, a_max, qd_start=qd_start)
    # The library keeps only the part of qd_start along the path; when the rest is more than
    # one small step, decelerate first (common factor) and start the path from rest.
    if np.max(np.abs(np.asarray(trajectory.sample(0.0)[1]) - qd_start)) > 1e-3 * np.min(a_max):
        first = (stop_segment(q_start, qd_start, a_max),)
        path[0] = first[0].q1
        keep = np.concatenate([[True], np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)])
        trajectory = timing.time_parameterize(path[keep], velocity_limits, a_max)
    t0 = first[0].duration if first else 0.0
    duration = float(trajectory.duration)
    # The library knows when it passes each path point (corner arcs: their middle). A waypoint
    # dropped as a repeat of the row before passes together with the kept row it repeats.
    passes = np.asarray(trajectory.waypoint_times, dtype=float)
    kept_row = np.cumsum(keep) - 1
    times = t0 + passes[kept_row[1:]]
    times[-1] = t0 + duration
    segment = TrajectorySegment(trajectory, duration, waypoints[-1].copy())
    return MotionPlan(first + (segment,), waypoints, np.array(times))


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


def _nearest_passes(trajectory, points, duration):
    """Return when ``trajectory`` passes nearest each of ``points`` (k, n), in order [s]."""
    ts = np.linspace(0.0, duration, max(400, 40 * len(points)))
    q = np.asarray(trajectory.sample(ts)[0])
    times, start = [], 0
    for point in points:
        i = start + int(np.argmin(np.linalg.norm(q[start:] - point, axis=1)))
        times.append(ts[i])
        start = i
    return np.array(times)


# [rad] Splines through points much closer than their neighbours swing far between them (and
# the common time factor then stretches the whole motion): the measured start lies a fraction of
# a milliradian from the planner's first waypoint. Rows closer than this to the last kept row
# are passed with it (the goal always kept exactly, replacing a row too close before it).
MERGE_STEP = 1e-3


def _spaced_rows(path, step):
    """Return which rows of ``path`` (k, n) to keep: the first, the last, none closer than step."""
    keep = np.zeros(len(path), dtype=bool)
    keep[0] = True
    last = 0
    for i in range(1, len(path)):
        if np.max(np.abs(path[i] - path[last])) > step:
            keep[i], last = True, i
    if len(path) > 1 and not keep[-1]:
        if last > 0 and np.max(np.abs(path[-1] - path[last])) <= step:
            keep[last] = False
        keep[-1] = np.max(np.abs(path[-1] - path[0])) > 1e-12
    return keep


def _through_all_plan(q_start, waypoints, velocity_limits, config, qd_start):
    """Plan a multi-point trajectory of the Jacobians and trajectories report (no stops)."""
    n = q_start.shape[0]
    a_max = as_positive(config.a_max, 'a_max', n)
    first = ()
    if np.any(qd_start):
        first = (stop_segment(q_start, qd_start, a_max),)
        q_start = first[0].q1
    path = np.vstack([q_start, waypoints])
    keep = _spaced_rows(path, MERGE_STEP)
    t0 = first[0].duration if first else 0.0
    if keep.sum() < 2:
        return MotionPlan(first, waypoints, np.full(len(waypoints), t0))
    trajectory = THROUGH_ALL_TRAJECTORIES[config.profile](path[keep], velocity_limits, a_max)
    duration = float(trajectory.duration)
    if config.profile in ('cubic_spline', 'quintic_spline'):
        # Interpolating: the knots are the waypoints, spaced as the slowest joint at its limit,
        # all scaled by one factor (``trajectories._fit_to_limits``).
        steps = np.max(np.abs(np.diff(path[keep], axis=0)) / velocity_limits, axis=1)
        passes = np.cumsum(steps) * duration / steps.sum()
    else:
        # Approximating (corners cut): when the reference passes nearest each waypoint.
        passes = _nearest_passes(trajectory, path[keep][1:], duration)
    kept_row = np.cumsum(keep) - 1
    passes = np.concatenate([[0.0], passes])
    times = t0 + passes[kept_row[1:]]
    times[-1] = t0 + duration
    segment = TrajectorySegment(trajectory, duration, waypoints[-1].copy())
    return MotionPlan(first + (segment,), waypoints, np.array(times))


def plan_motion(config: LawConfig, q_start: Sequence[float], waypoints: np.ndarray,
                velocity_limits: Sequence[float],
                qd_start: Optional[Sequence[float]] = None) -> MotionPlan:
    """
    Return the ``MotionPlan`` of ``config.profile`` from ``q_start`` (n,) via ``waypoints`` (N, n).

    ``velocity_limits`` (n,) [rad/s]; ``qd_start`` (n,) [rad/s] is the velocity commanded now
    (None: at rest). ruckig and the continuous law start from it; every other law first
    decelerates from it (common factor, ``a_max``), then starts. Waypoints are not checked
    against position limits here (the caller does).
    """
    q_start, waypoints, velocity_limits, qd_start = _check_inputs(
        q_start, waypoints, velocity_limits, qd_start)
    if config.profile == 'continuous':
        return _continuous_plan(q_start, waypoints, velocity_limits, config, qd_start)
    if config.profile == 'jerk_limited':
        # ruckig, rest to rest per waypoint (the first from the present velocity).
        segments, times, q0, qd0, t = [], [], q_start, qd_start, 0.0
        for q1 in waypoints:
            move = ruckig_trajectory(q0, q1, velocity_limits, config.a_max, config.j_max, qd0)
            segments.append(TrajectorySegment(move, move.duration, q1.copy()))
            t += move.duration
            times.append(t)
            q0, qd0 = q1, None
        return MotionPlan(tuple(segments), waypoints, np.array(times))
    if config.profile in THROUGH_ALL_TRAJECTORIES:
        return _through_all_plan(q_start, waypoints, velocity_limits, config, qd_start)
    first = ()
    if np.any(qd_start):
        first = (stop_segment(q_start, qd_start, config.a_max),)
        q_start = first[0].q1
    if config.profile in STOP_AT_EACH_LAWS:
        law = STOP_AT_EACH_LAWS[config.profile]()
        return _per_waypoint(q_start, waypoints, lambda a, b: time_law_segment(
            a, b, law, velocity_limits, config.a_max), first)
    if config.profile == 'synchronised':
        return _per_waypoint(q_start, waypoints, lambda a, b: synchronised_segment(
            a, b, config.lambda_max, velocity_limits), first)
    return _per_waypoint(q_start, waypoints, lambda a, b: trapezoid_segment(
        a, b, config.t_max, config.blend, velocity_limits), first)


def predicted_duration(profile: str, q_start: Sequence[float], waypoints: np.ndarray,
                       velocity_limits: Sequence[float]) -> float:
    """
    Return the duration [s] the controller plans for ``waypoints`` from rest at ``q_start``.

    The one timing model: ``plan_motion`` with ``profile`` and the controller's default law
    settings (``LawConfig``'s defaults are the controller node's), as the planner announces it.
    """
    return plan_motion(LawConfig(profile=profile), q_start, waypoints, velocity_limits).duration
