"""
Why a pose or a path has no IK solution: the ``UnreachableError`` and its details.

``unreachable_error`` tells a pose reachable only outside the joint limits ('joint_limits')
from one out of reach ('out_of_reach') and finds the closest pose inside the limits;
``path_failure`` is the error of a path that fails at a waypoint for another reason
(``path_ik.solve_path``: a discontinuity, a singularity), its closest pose the last one reached
continuously. Either error's ``details`` hold 'waypoint', 'position_error' [m],
'orientation_error' [rad], 'closest_q', 'closest_pose' and 'message'.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from mover6_control.errors import UnreachableError
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.ik_closed_form import solve_candidates
from mover6_control.kinematics.ik_numeric import closest_within_limits, DEFAULT_WEIGHTS, ik_numeric
from mover6_control.kinematics.rotations import pose_error
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel
    from mover6_control.kinematics.wrist import WristGeometry


def _closest(arm, T, seeds, weights):
    """Return (q, pose, position error, orientation error) of the closest in-limit config."""
    res = closest_within_limits(arm, T, seeds, weights=weights)
    pose = fk(arm, res.q)
    pos, rot = pose_error(pose, T)
    return res.q, pose, pos, rot


def unreachable_error(arm: ArmModel, T: np.ndarray, q_seed: np.ndarray, waypoint: int,
                      weights: Sequence[float] = DEFAULT_WEIGHTS,
                      geometry: WristGeometry | None = None,
                      what: str = 'the pose') -> UnreachableError:
    """
    Return the ``UnreachableError`` for a pose with no solution inside the limits.

    Tells 'joint_limits' (solutions exist outside the limits; the message names the joints)
    from 'out_of_reach', and finds the closest pose inside the limits. ``what`` is 'waypoint'
    (the message then names its index) or a noun for the message.
    """
    if geometry is not None:
        Q, ok = solve_candidates(arm, geometry, T[None], q_seed[None], within_limits=False)
        outside = Q[0][ok[0]]
    else:
        res = ik_numeric(arm, T, q_seed, within_limits=False, rng=waypoint)
        outside = res.q[None] if res.success else np.zeros((0, arm.n_joints))
    seeds = [q_seed]
    if len(outside):
        # The unconstrained solution that needs the least limit violation.
        over = np.maximum(arm.lower - outside, 0.0) + np.maximum(outside - arm.upper, 0.0)
        best = outside[np.argmin(over.sum(axis=1))]
        seeds.append(np.clip(best, arm.lower, arm.upper))
    q, pose, pos, rot = _closest(arm, T, np.array(seeds), weights)
    closest = (f'closest pose inside the limits misses it by {pos * 1e3:.1f} mm and '
               f'{rot:.4f} rad')
    what = f'waypoint {waypoint}' if what == 'waypoint' else what
    if len(outside):
        reason = 'joint_limits'
        message = (f'{what} is reachable only outside the joint limits ('
                   + '; '.join(arm.limit_violations(best)) + f'); {closest}')
    else:
        reason = 'out_of_reach'
        message = f'{what} is out of reach; {closest}'
    details = {'waypoint': int(waypoint), 'position_error': pos, 'orientation_error': rot,
               'closest_q': q, 'closest_pose': pose, 'message': message}
    if len(outside):
        details['q_outside_limits'] = best
    return UnreachableError(message, reason=reason, details=details)


def path_failure(arm: ArmModel, T: np.ndarray, q_prev: np.ndarray, k: int, reason: str,
                 message: str, extra: dict) -> UnreachableError:
    """Return the ``UnreachableError`` of waypoint ``k``; the closest pose is ``q_prev``'s."""
    pose = fk(arm, q_prev)
    pos, rot = pose_error(pose, T)
    details = {'waypoint': int(k), 'position_error': pos, 'orientation_error': rot,
               'closest_q': q_prev, 'closest_pose': pose, 'message': message}
    details.update(extra)
    return UnreachableError(message, reason=reason, details=details)
