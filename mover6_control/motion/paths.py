"""
Cartesian pose paths: sequences of tool poses ``T_base_tool`` (n, 4, 4) for path IK.

Positions [m] follow the path's curve; orientations are interpolated by SLERP (scipy's
``Slerp``) along the same parameter. Every builder samples either ``n`` poses, or as few as
keep each step within ``max_step`` [m] and ``max_angle_step`` [rad] (give one of the two
forms). The first pose is the start and the last the goal, exactly.

Shapes: linear (the Mover6 report eq. 3-10), parabolic through a lifted mid-point (the Mover6
report eq. 11-15), cubic spline through any number of via poses (the Mover6 report section 2.3.2),
circular arc through a via point.

Each ``*_curve`` builder returns a ``PosePath``: the poses (``poses``), their curve parameters,
and the curve itself (``pose_at``), so a solver can look between two samples
(``PosePath.between``) when a joint step there is too large.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import (rotation_angle_between, slerp,
                                                 validate_transform)
from mover6_control.validation import as_finite_array, as_positive
from mover6_control.values import poses_of, ToolPose
import numpy as np
from scipy.interpolate import CubicSpline

# Points closer than this [m] and rotations smaller than this [rad] count as coincident.
COINCIDENT_TOL = 1e-9
# Dense samples used to measure curve length and resample a curve by arc length.
_DENSE = 4001


@dataclass(frozen=True)
class PosePath:
    """
    Poses sampled on a curve: ``poses`` (n, 4, 4) at parameters ``params`` (n,) of ``pose_at``.

    ``pose_at(t)`` returns the poses (m, 4, 4) of the curve at parameters ``t`` (m,); the first
    and last samples are the start and goal exactly.
    """

    poses: np.ndarray
    params: np.ndarray
    pose_at: Callable[[np.ndarray], np.ndarray]

    def between(self, k: int, fractions: np.ndarray) -> np.ndarray:
        """Return poses (m, 4, 4) between sample ``k - 1`` (fraction 0) and ``k`` (1)."""
        if not 1 <= int(k) < len(self.params):
            raise InvalidInputError(f'no samples {k - 1} and {k} in a path of {len(self.params)}')
        s = np.asarray(fractions, dtype=float).reshape(-1)
        t0, t1 = self.params[int(k) - 1], self.params[int(k)]
        return self.pose_at(t0 + s * (t1 - t0))


def _count(n, max_step, max_angle_step, length, angle, rate_scale=1.0):
    """Return the number of poses: ``n``, or enough to keep steps within the given maxima."""
    if n is not None:
        if max_step is not None or max_angle_step is not None:
            raise InvalidInputError('give either n or max_step / max_angle_step, not both')
        if int(n) != n or n < 2:
            raise InvalidInputError(f'n must be an integer >= 2, got {n}')
        return int(n)
    if max_step is None and max_angle_step is None:
        raise InvalidInputError('give n, max_step [m] or max_angle_step [rad]')
    steps = 1
    for limit, amount, name in ((max_step, length * rate_scale, 'max_step'),
                                (max_angle_step, angle, 'max_angle_step')):
        if limit is None:
            continue
        limit = as_positive(limit, name)
        steps = max(steps, int(np.ceil(amount / limit - 1e-12)))
    return steps + 1


def _poses(positions, rotations):
    T = np.tile(np.eye(4), (positions.shape[0], 1, 1))
    T[:, :3, 3] = positions
    T[:, :3, :3] = rotations
    return T


def _pin_ends(T, T_start, T_goal):
    T[0] = T_start
    T[-1] = T_goal
    return T


def _check_distinct(T_a, T_b, what):
    dp = np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])
    da = rotation_angle_between(T_a[:3, :3], T_b[:3, :3])
    if dp < COINCIDENT_TOL and da < COINCIDENT_TOL:
        raise InvalidInputError(f'{what} coincide: there is no path between them')
    return dp, da


def _sampled(pose_at, params, T_start, T_goal):
    params = np.asarray(params, dtype=float)
    return PosePath(_pin_ends(pose_at(params), T_start, T_goal), params, pose_at)


def linear_curve(T_start: np.ndarray, T_goal: np.ndarray, n: Optional[int] = None,
                 max_step: Optional[float] = None,
                 max_angle_step: Optional[float] = None) -> PosePath:
    """
    Return the ``PosePath`` on the straight line from ``T_start`` to ``T_goal``.

    Position ``p(t) = (1 - t) p_start + t p_goal`` (the Mover6 report eq. 4) and SLERPed
    orientation, ``t`` evenly spaced in [0, 1].
    """
    T_start = validate_transform(T_start, 'T_start')
    T_goal = validate_transform(T_goal, 'T_goal')
    length, angle = _check_distinct(T_start, T_goal, 'start and goal poses')
    count = _count(n, max_step, max_angle_step, length, angle)

    def pose_at(t):
        t = np.asarray(t, dtype=float)
        pos = (1.0 - t)[:, None] * T_start[:3, 3] + t[:, None] * T_goal[:3, 3]
        return _poses(pos, slerp([0.0, 1.0], [T_start[:3, :3], T_goal[:3, :3]], t))

    return _sampled(pose_at, np.linspace(0.0, 1.0, count), T_start, T_goal)


def parabola_coefficients(p_start: Sequence[float], p_mid: Sequence[float],
                          p_goal: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (a, b, c) (3,) each with ``r(t) = a t^2 + b t + c`` through the three points.

    ``r(0) = p_start``, ``r(0.5) = p_mid``, ``r(1) = p_goal`` (the Mover6 report eq. 12-15).
    The points come from poses already checked (``parabolic_curve``'s): not checked again.
    """
    M = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.25, 0.5, 1.0]])
    rhs = np.array([p_start, p_goal, p_mid], dtype=float)
    coeff = np.linalg.solve(M, rhs)
    return coeff[0], coeff[1], coeff[2]


def parabolic_curve(T_start: np.ndarray, T_goal: np.ndarray, peak_height: float,
                    n: Optional[int] = None, max_step: Optional[float] = None,
                    max_angle_step: Optional[float] = None) -> PosePath:
    """
    Return the ``PosePath`` on the Mover6 report's parabola from ``T_start`` to ``T_goal``.

    The curve passes at ``t = 0.5`` through the mid-point of start and goal raised by
    ``peak_height`` [m] along the base z axis (the Mover6 report eq. 11-15); ``t`` is evenly
    spaced in [0, 1].
    """
    T_start = validate_transform(T_start, 'T_start')
    T_goal = validate_transform(T_goal, 'T_goal')
    peak = float(as_finite_array(peak_height, (), 'peak_height'))
    mid = 0.5 * (T_start[:3, 3] + T_goal[:3, 3]) + np.array([0.0, 0.0, peak])
    return parabolic_curve_through(T_start, mid, T_goal, n, max_step, max_angle_step)


def parabolic_curve_through(T_start, p_peak, T_goal, n=None, max_step=None,
                            max_angle_step=None) -> PosePath:
    """
    Return the ``PosePath`` on the parabola through start, ``p_peak`` (3,) [m] and goal.

    The Mover6 report's eq. 12: ``r(0)`` the start, ``r(0.5)`` the peak, ``r(1)`` the goal;
    the orientation is SLERPed from start to goal and ``t`` is evenly spaced in [0, 1].
    """
    T_start = validate_transform(T_start, 'T_start')
    T_goal = validate_transform(T_goal, 'T_goal')
    mid = as_finite_array(p_peak, (3,), 'p_peak')
    _check_distinct(T_start, T_goal, 'start and goal poses')
    p0, p1 = T_start[:3, 3], T_goal[:3, 3]
    a, b, c = parabola_coefficients(p0, mid, p1)
    # |r'(t)| = |2 a t + b| is convex in t: its largest value is at an end.
    top_rate = max(np.linalg.norm(b), np.linalg.norm(2.0 * a + b))
    angle = rotation_angle_between(T_start[:3, :3], T_goal[:3, :3])
    count = _count(n, max_step, max_angle_step, top_rate, angle)

    def pose_at(t):
        t = np.asarray(t, dtype=float)
        pos = np.outer(t ** 2, a) + np.outer(t, b) + c
        return _poses(pos, slerp([0.0, 1.0], [T_start[:3, :3], T_goal[:3, :3]], t))

    return _sampled(pose_at, np.linspace(0.0, 1.0, count), T_start, T_goal)


def _resample_by_length(curve, count):
    """Return curve parameters (count,) in [0, 1] evenly spaced in arc length, and the length."""
    u = np.linspace(0.0, 1.0, _DENSE)
    pts = curve(u)
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    if count is None:
        return None, float(cum[-1])
    return np.interp(np.linspace(0.0, cum[-1], count), cum, u), float(cum[-1])


def spline_curve(T_start: np.ndarray, T_vias: np.ndarray, T_goal: np.ndarray,
                 n: Optional[int] = None, max_step: Optional[float] = None,
                 max_angle_step: Optional[float] = None) -> PosePath:
    """
    Return the ``PosePath`` on a cubic spline through ``T_start``, every via pose and ``T_goal``.

    ``T_vias`` is (k, 4, 4) with any k >= 0. The spline is C2 ('natural' ends) in a chord-length
    parameter ``u``, sampled evenly in arc length; orientation is SLERPed between consecutive key
    poses, reaching each via orientation at its via point.
    """
    T_start = validate_transform(T_start, 'T_start')
    T_goal = validate_transform(T_goal, 'T_goal')
    vias = [] if np.size(T_vias) == 0 else [p.matrix for p in poses_of(T_vias, 'T_vias')]
    keys = [T_start] + vias + [T_goal]
    for i in range(len(keys) - 1):
        _check_distinct(keys[i], keys[i + 1], f'key poses {i} and {i + 1}')
    P = np.array([T[:3, 3] for T in keys])
    R = np.array([T[:3, :3] for T in keys])
    chords = np.linalg.norm(np.diff(P, axis=0), axis=1)
    turns = np.array([rotation_angle_between(R[i], R[i + 1]) for i in range(len(keys) - 1)])
    # Chord length, with a little of the turn so a pure rotation still advances the parameter.
    steps = chords + 1e-3 * turns
    u_keys = np.concatenate([[0.0], np.cumsum(steps)]) / steps.sum()
    curve = CubicSpline(u_keys, P, axis=0, bc_type='natural')
    _, length = _resample_by_length(curve, None)
    count = _count(n, max_step, max_angle_step, length, turns.sum())
    u, _ = _resample_by_length(curve, count)
    if length < COINCIDENT_TOL:
        u = np.linspace(0.0, 1.0, count)

    def pose_at(t):
        t = np.asarray(t, dtype=float)
        return _poses(curve(t), slerp(u_keys, R, t))

    return _sampled(pose_at, u, T_start, T_goal)


def circle_through(p_a: Sequence[float], p_b: Sequence[float],
                   p_c: Sequence[float]) -> tuple[np.ndarray, float, np.ndarray, np.ndarray,
                                                  float, float]:
    """
    Return (center (3,), radius [m], e1 (3,), e2 (3,), angle_b, angle_c) of the circle A-B-C.

    A point at angle ``phi`` is ``center + radius (e1 cos phi + e2 sin phi)``; A is at 0 and
    ``0 < angle_b < angle_c < 2 pi``. Collinear points have no circle: an error. The points
    come from poses and a via point already checked (``arc_curve``'s): not checked again.
    """
    A, B, C = (np.asarray(p, dtype=float) for p in (p_a, p_b, p_c))
    ab, ac = B - A, C - A
    normal = np.cross(ab, ac)
    scale = np.linalg.norm(ab) * np.linalg.norm(ac)
    if scale < COINCIDENT_TOL ** 2 or np.linalg.norm(normal) < 1e-9 * scale \
            or np.linalg.norm(C - B) < COINCIDENT_TOL:
        raise InvalidInputError('arc points are collinear or coincide: no unique circle')
    nn = normal @ normal
    center = A + (np.cross(normal, ab) * (ac @ ac) + np.cross(ac, normal) * (ab @ ab)) / (2 * nn)
    radius = float(np.linalg.norm(A - center))
    e1 = (A - center) / radius
    e2 = np.cross(normal / np.sqrt(nn), e1)

    def angle(P):
        d = P - center
        return float(np.mod(np.arctan2(d @ e2, d @ e1), 2.0 * np.pi))

    return center, radius, e1, e2, angle(B), angle(C)


def arc_curve(T_start: np.ndarray, T_via: np.ndarray, T_goal: np.ndarray,
              n: Optional[int] = None, max_step: Optional[float] = None,
              max_angle_step: Optional[float] = None) -> PosePath:
    """
    Return the ``PosePath`` on the circular arc from ``T_start`` through a via point to ``T_goal``.

    ``T_via`` is a pose (4, 4) or a point (3,) [m]. Samples are evenly spaced in angle (``t`` in
    [0, 1] along it). The orientation is SLERPed from start to goal, through the via orientation
    at the via point when a via pose is given.
    """
    T_start = validate_transform(T_start, 'T_start')
    T_goal = validate_transform(T_goal, 'T_goal')
    via = T_via if isinstance(T_via, ToolPose) else np.asarray(T_via, dtype=float)
    T_via = validate_transform(via, 'T_via') if np.shape(via) == (4, 4) else None
    p_via = T_via[:3, 3] if T_via is not None else as_finite_array(via, (3,), 'T_via')
    center, radius, e1, e2, ang_b, ang_c = circle_through(T_start[:3, 3], p_via, T_goal[:3, 3])
    if T_via is None:
        keys, R = [0.0, 1.0], [T_start[:3, :3], T_goal[:3, :3]]
    else:
        keys = [0.0, ang_b / ang_c, 1.0]
        R = [T_start[:3, :3], T_via[:3, :3], T_goal[:3, :3]]
    turn = sum(rotation_angle_between(R[i], R[i + 1]) for i in range(len(R) - 1))
    count = _count(n, max_step, max_angle_step, radius * ang_c, turn)

    def pose_at(t):
        phi = np.asarray(t, dtype=float) * ang_c
        pos = center + radius * (np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2))
        return _poses(pos, slerp(keys, R, t))

    return _sampled(pose_at, np.linspace(0.0, 1.0, count), T_start, T_goal)


def positions_of(poses: np.ndarray) -> np.ndarray:
    """Return the positions (n, 3) [m] of poses (n, 4, 4) (a path's: computed, not checked)."""
    return np.array(poses, dtype=float)[:, :3, 3]
