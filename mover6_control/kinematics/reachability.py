"""
Reachability verdicts for a pose or a path: reachable, or why not and how close one can get.

A verdict answers with a reason code (``errors.REASONS``), a sentence for a human, the solution
when there is one, and the closest pose found inside the joint limits with its position [m] and
orientation [rad] errors when there is none. ``check_path`` wraps ``path_ik.solve_path`` and
turns its ``UnreachableError`` into a verdict.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Optional, TYPE_CHECKING

from mover6_control.errors import UnreachableError
from mover6_control.kinematics.forward import condition_number, fk
from mover6_control.kinematics.ik_closed_form import ik_closed_form
from mover6_control.kinematics.ik_numeric import DEFAULT_WEIGHTS, ik_numeric
from mover6_control.kinematics.path_ik import solve_path, validate_poses
from mover6_control.kinematics.rotations import pose_error
from mover6_control.kinematics.unreachable import unreachable_error
from mover6_control.kinematics.wrist import has_spherical_wrist, wrist_geometry
from mover6_control.values import ToolPose
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel


@dataclass(frozen=True)
class Verdict:
    """Whether a pose (or path) is reachable; if not, why, and the closest pose found."""

    reachable: bool
    reason: str                  # one of errors.REASONS
    message: str                 # a sentence for a human
    q: Optional[np.ndarray]      # (n,) for a pose, (m, n) for a path; None when unreachable
    closest_pose: np.ndarray     # (4, 4): the pose reached (== the goal when reachable)
    position_error: float        # [m] closest_pose against the goal
    orientation_error: float     # [rad]
    waypoint: Optional[int] = None           # the failing waypoint of a path
    solutions: Optional[np.ndarray] = None   # (k, n) every in-limit solution of a pose
    details: dict = field(default_factory=dict)


def _from_error(err, q=None):
    """Turn an ``UnreachableError`` from the path solver into a ``Verdict``."""
    d = err.details
    return Verdict(reachable=False, reason=err.reason, message=str(err), q=q,
                   closest_pose=d['closest_pose'], position_error=float(d['position_error']),
                   orientation_error=float(d['orientation_error']),
                   waypoint=d.get('waypoint'), details=dict(d))


def check_pose(arm: ArmModel, T: np.ndarray, q_ref: np.ndarray | None = None, *,
               max_condition: float | None = None, position_tol: float = 1e-3,
               orientation_tol: float = 0.01,
               weights: Sequence[float] = DEFAULT_WEIGHTS) -> Verdict:
    """
    Return the ``Verdict`` for one pose ``T`` (4, 4) [m].

    ``q_ref`` (n,) [rad] picks among several solutions (the nearest; default zeros).
    ``max_condition`` (None: no check) rejects a pose all of whose in-limit solutions have a
    Jacobian condition number above it (reason 'singularity'). Arms without a spherical wrist
    are solved numerically to ``position_tol`` [m] and ``orientation_tol`` [rad].
    """
    T = ToolPose.of(T, 'pose')          # checked once here; the IK below takes it as it is
    ref = np.zeros(arm.n_joints) if q_ref is None else arm.check_q(q_ref, 'q_ref')
    closed_form = has_spherical_wrist(arm)
    sols = np.zeros((0, arm.n_joints))
    if closed_form:
        sols = ik_closed_form(arm, T, within_limits=True, q_ref=ref)
    if len(sols) == 0:
        # Numeric IK: for arms without a closed form, and as a fallback for poses the closed
        # form misses by rounding (a fully stretched arm, say).
        res = ik_numeric(arm, T, ref, position_tol=min(position_tol, 1e-6),
                         orientation_tol=min(orientation_tol, 1e-6), weights=weights)
        sols = res.q[None] if res.success else sols
    if len(sols) == 0:
        geometry = wrist_geometry(arm) if closed_form else None
        return _from_error(unreachable_error(arm, T, ref, 0, weights, geometry))
    conds = np.array([condition_number(arm, q) for q in sols])
    usable = np.ones(len(sols), dtype=bool) if max_condition is None else conds <= max_condition
    if not usable.any():
        k = int(np.argmin(conds))
        pose = fk(arm, sols[k])
        pos, rot = pose_error(pose, T)
        return Verdict(
            reachable=False, reason='singularity',
            message=(f'the pose is reachable only near a singularity (best Jacobian condition '
                     f'number {conds[k]:.3g} > {max_condition:.3g})'),
            q=None, closest_pose=pose, position_error=pos, orientation_error=rot,
            solutions=sols, details={'condition': float(conds[k]), 'closest_q': sols[k]})
    idx = np.flatnonzero(usable)
    k = idx[np.argmin(np.abs(sols[idx] - ref).max(axis=1))]
    pose = fk(arm, sols[k])
    pos, rot = pose_error(pose, T)
    return Verdict(reachable=True, reason='reachable',
                   message=(f'the pose is reachable: {len(sols)} solution(s) inside the joint '
                            f'limits, condition number {conds[k]:.3g} at the nearest'),
                   q=sols[k], closest_pose=pose, position_error=pos, orientation_error=rot,
                   solutions=sols, details={'condition': float(conds[k])})


def check_path(arm: ArmModel, poses: np.ndarray, q_start: np.ndarray,
               **settings: object) -> Verdict:
    """
    Return the ``Verdict`` for a pose path (m, 4, 4) from ``q_start`` (n,) [rad].

    ``settings`` go to ``path_ik.solve_path`` (max_joint_step, max_condition, position_tol,
    orientation_tol, weights). When reachable, ``q`` is the (m, n) joint path and
    ``closest_pose`` the pose reached at the last waypoint.
    """
    P = validate_poses(poses)
    try:
        sol = solve_path(arm, P, q_start, **settings)
    except UnreachableError as err:
        return _from_error(err)
    pose = fk(arm, sol.q[-1])
    pos, rot = pose_error(pose, P[-1])
    return Verdict(reachable=True, reason='reachable',
                   message=(f'the path is reachable: {len(P)} waypoints, largest joint step '
                            f'{sol.max_joint_step:.3f} rad, largest condition number '
                            f'{sol.max_condition:.3g}'),
                   q=sol.q, closest_pose=pose, position_error=pos, orientation_error=rot,
                   details={'max_joint_step': sol.max_joint_step,
                            'max_condition': sol.max_condition})
