"""
The planners of the profiles: ``plan_motion`` turns waypoints into a profile's ``MotionPlan``.

``plan_motion(config, q_start, waypoints, velocity_limits, qd_start)`` plans with
``config.profile`` (``control.profiles``). A plan started while the arm moves begins from the
present commanded velocity: ruckig and the continuous profile start from it directly, every
other profile first decelerates from it (common factor, ``a_max``). So replacing a motion never
makes the command jump. ``predicted_duration`` is the same planning with the controller's
default settings, as the planner announces it (the one timing model).
"""

from __future__ import annotations

from typing import Optional, Sequence

from mover6_control.control.motion_plan import (MotionPlan, stop_segment, synchronised_segment,
                                                time_law_segment, TrajectorySegment,
                                                trapezoid_segment)
from mover6_control.control.profiles import (LawConfig, STOP_AT_EACH_PROFILES,
                                             THROUGH_ALL_PROFILES)
from mover6_control.errors import InvalidInputError
# Imported with this module, not lazily in the first continuous demand's callback: that import
# (scipy.interpolate; 0.1 s idle, far longer on a loaded machine) held up the controller.
from mover6_control.motion.timing import time_optimal
from mover6_control.motion.timing.jerk_limited import ruckig_trajectory
from mover6_control.validation import as_positive
import numpy as np


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
    a_max = np.full(n, float(config.a_max))     # checked when the profile was loaded
    first = ()
    path = np.vstack([q_start, waypoints])
    keep = np.concatenate([[True], np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)])
    if keep.sum() < 2:
        return MotionPlan((), waypoints, np.zeros(len(waypoints)))
    trajectory = time_optimal.time_parameterize(path[keep], velocity_limits, a_max,
                                                qd_start=qd_start)
    # The library keeps only the part of qd_start along the path; when the rest is more than
    # one small step, decelerate first (common factor) and start the path from rest.
    if np.max(np.abs(np.asarray(trajectory.sample(0.0)[1]) - qd_start)) > 1e-3 * np.min(a_max):
        first = (stop_segment(q_start, qd_start, a_max),)
        path[0] = first[0].q1
        keep = np.concatenate([[True], np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)])
        trajectory = time_optimal.time_parameterize(path[keep], velocity_limits, a_max)
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
    a_max = np.full(n, float(config.a_max))     # checked when the profile was loaded
    first = ()
    if np.any(qd_start):
        first = (stop_segment(q_start, qd_start, a_max),)
        q_start = first[0].q1
    path = np.vstack([q_start, waypoints])
    keep = _spaced_rows(path, MERGE_STEP)
    t0 = first[0].duration if first else 0.0
    if keep.sum() < 2:
        return MotionPlan(first, waypoints, np.full(len(waypoints), t0))
    trajectory = THROUGH_ALL_PROFILES[config.profile](path[keep], velocity_limits, a_max)
    duration = float(trajectory.duration)
    if config.profile in ('cubic_spline', 'quintic_spline'):
        # Interpolating: the knots are the waypoints, spaced as the slowest joint at its limit,
        # all scaled by one factor (``spline_trajectories._fit_to_limits``).
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
    if config.profile in THROUGH_ALL_PROFILES:
        return _through_all_plan(q_start, waypoints, velocity_limits, config, qd_start)
    first = ()
    if np.any(qd_start):
        first = (stop_segment(q_start, qd_start, config.a_max),)
        q_start = first[0].q1
    if config.profile in STOP_AT_EACH_PROFILES:
        law = STOP_AT_EACH_PROFILES[config.profile]()
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
