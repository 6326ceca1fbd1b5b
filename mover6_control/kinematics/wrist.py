"""
The wrist geometry that the closed-form IK solvers build on: an arm's screws at ``q = 0``.

``wrist_geometry`` reads a 6R ``ArmModel`` into a ``WristGeometry`` (its joint axes and a point
on each, the tip pose and the wrist centre), or says with the reason why the closed form cannot
solve it (no spherical wrist, no planar elbow ...). The batch solver (``ik_closed_form``) and the
one-pose solver (``ik_one_pose``) both take it from here; ``VERIFY_TOL`` is the forward
kinematics round trip both ask of a solution.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from mover6_control.errors import InvalidInputError
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

VERIFY_TOL = 1e-6        # [m] and [rad]: an FK round trip worse than this is not a solution
_PARALLEL_TOL = 1e-7     # |omega_a x omega_b| under this: parallel axes (URDF rounding)
_POINT_TOL = 1e-7        # [m] axes that pass closer than this meet


@dataclass(frozen=True, eq=False)
class WristGeometry:
    """Space-frame screws at ``q = 0`` of a 6R arm that the closed form can solve."""

    omega: np.ndarray         # (6, 3) unit joint axes in the base frame at q = 0
    r: np.ndarray             # (6, 3) a point on each axis [m]
    M: np.ndarray             # (4, 4) tip pose at q = 0
    wrist_point: np.ndarray   # (3,) wrist centre at q = 0, base frame [m]
    wrist_in_tip: np.ndarray  # (3,) wrist centre in the tip frame [m] (constant)
    x6: np.ndarray            # (3,) a unit vector normal to omega_6


def cross3(a, b):
    """Return the cross product of (..., 3) arrays (np.cross is slow on small inputs)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast(a, b).shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def norm3(v):
    """Return the Euclidean norm of a 3-vector as a float."""
    return float(np.sqrt(v @ v))


def wrist_geometry(arm: ArmModel) -> WristGeometry:
    """
    Return the ``WristGeometry`` of ``arm`` or raise ``InvalidInputError`` saying what is missing.

    Requires 6 revolute joints, axes 4-6 meeting in a point, axes 2 and 3 parallel and axis 1
    not parallel to them.
    """
    if arm.n_joints != 6:
        raise InvalidInputError(
            f'closed-form IK needs a 6-joint arm, {arm.name} has {arm.n_joints}')
    frames = np.empty((7, 4, 4))      # at q = 0 every joint rotation is the identity
    frames[0] = arm.origins[0]
    for i in range(1, 6):
        frames[i] = frames[i - 1] @ arm.origins[i]
    frames[6] = frames[5] @ arm.tool
    omega = np.einsum('nij,nj->ni', frames[:6, :3, :3], arm.axes)
    r = frames[:6, :3, 3].copy()
    # Least-squares point nearest to the three wrist axes.
    A = np.zeros((3, 3))
    rhs = np.zeros(3)
    for i in (3, 4, 5):
        P = np.eye(3) - np.outer(omega[i], omega[i])
        A += P
        rhs += P @ r[i]
    if norm3(cross3(omega[3], omega[4])) < 1e-6 or norm3(
            cross3(omega[4], omega[5])) < 1e-6:
        raise InvalidInputError(f'{arm.name}: neighbouring wrist axes are parallel; '
                                'no spherical wrist (use ik_numeric)')
    centre = np.linalg.solve(A, rhs)
    for i in (3, 4, 5):
        off = (centre - r[i]) - np.dot(centre - r[i], omega[i]) * omega[i]
        if norm3(off) > _POINT_TOL:
            raise InvalidInputError(
                f'{arm.name}: axes 4, 5, 6 do not meet in one point (axis {i + 1} misses it by '
                f'{norm3(off):.3g} m); no spherical wrist (use ik_numeric)')
    if norm3(cross3(omega[1], omega[2])) > _PARALLEL_TOL:
        raise InvalidInputError(
            f'{arm.name}: axes 2 and 3 are not parallel; this closed form needs a planar elbow '
            '(use ik_numeric)')
    if norm3(cross3(omega[0], omega[1])) < 1e-6:
        raise InvalidInputError(f'{arm.name}: axis 1 is parallel to axis 2 (use ik_numeric)')
    w2 = omega[1]
    e = (r[2] - r[1]) - np.dot(r[2] - r[1], w2) * w2
    u = (centre - r[2]) - np.dot(centre - r[2], w2) * w2
    if norm3(e) < _POINT_TOL or norm3(u) < _POINT_TOL:
        raise InvalidInputError(f'{arm.name}: degenerate elbow (zero link length)')
    M = frames[6]
    x6 = cross3(omega[5], [1.0, 0.0, 0.0])
    if norm3(x6) < 0.5:
        x6 = cross3(omega[5], [0.0, 1.0, 0.0])
    geometry = WristGeometry(omega=omega, r=r, M=M, wrist_point=centre,
                             wrist_in_tip=M[:3, :3].T @ (centre - M[:3, 3]),
                             x6=x6 / norm3(x6))
    return geometry


def has_spherical_wrist(arm: ArmModel) -> bool:
    """Return True when ``ik_closed_form`` can solve ``arm``."""
    try:
        wrist_geometry(arm)
    except InvalidInputError:
        return False
    return True
