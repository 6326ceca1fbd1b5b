"""
Rotations and homogeneous transforms: validation and conversions.

Conventions:
- A pose is a 4x4 homogeneous transform ``T_base_tool`` [m].
- Euler angles follow the Mover6 report (MATLAB's default ZYX): ``R = Rz(A) @ Ry(B) @ Rx(C)``, so A
  is yaw, B pitch and C roll [rad].
- Quaternions are in ROS order ``(x, y, z, w)``.
"""

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_finite_array
import numpy as np
from scipy.spatial.transform import Rotation

ORTHONORMAL_TOL = 1e-6


def validate_rotation(R, name='rotation'):
    """Check that ``R`` is a finite 3x3 proper rotation matrix and return it as an array."""
    R = as_finite_array(R, (3, 3), name)
    err = np.abs(R.T @ R - np.eye(3)).max()
    if err > ORTHONORMAL_TOL:
        raise InvalidInputError(f'{name} is not orthonormal (|R^T R - I| = {err:.2e})')
    if np.linalg.det(R) < 0.0:
        raise InvalidInputError(f'{name} is a reflection (det < 0), not a rotation')
    return R


def validate_transform(T, name='transform'):
    """Check that ``T`` is a finite 4x4 homogeneous transform and return it as an array."""
    T = as_finite_array(T, (4, 4), name)
    validate_rotation(T[:3, :3], name + ' rotation')
    if np.abs(T[3] - np.array([0.0, 0.0, 0.0, 1.0])).max() > ORTHONORMAL_TOL:
        raise InvalidInputError(f'{name} last row must be [0, 0, 0, 1], got {T[3].tolist()}')
    return T


def make_transform(position, R=None):
    """Build ``T`` (4, 4) from a position (3,) [m] and a rotation matrix (3, 3)."""
    T = np.eye(4)
    T[:3, 3] = as_finite_array(position, (3,), 'position')
    if R is not None:
        T[:3, :3] = validate_rotation(R)
    return T


def euler_zyx_to_matrix(a, b, c):
    """Return ``Rz(a) @ Ry(b) @ Rx(c)`` (3, 3) for angles [rad] in MATLAB's default ZYX order."""
    angles = as_finite_array([a, b, c], (3,), 'euler angles')
    return Rotation.from_euler('ZYX', angles).as_matrix()


def matrix_to_euler_zyx(R):
    """Return (A, B, C) [rad] with ``R = Rz(A) Ry(B) Rx(C)``; B in [-pi/2, pi/2]."""
    R = validate_rotation(R)
    return tuple(float(x) for x in Rotation.from_matrix(R).as_euler('ZYX'))


def quaternion_to_matrix(q_xyzw):
    """
    Return the rotation matrix of a quaternion ``(x, y, z, w)``; rejects a zero quaternion.

    A quaternion whose norm is off 1 by more than 1e-3 is rejected too, because a sender that
    means a rotation normalises it; silently normalising would hide a bug upstream.
    """
    q = as_finite_array(q_xyzw, (4,), 'quaternion')
    norm = float(np.linalg.norm(q))
    if norm < 1e-9:
        raise InvalidInputError('quaternion is zero: it describes no rotation')
    if abs(norm - 1.0) > 1e-3:
        raise InvalidInputError(f'quaternion is not unit length (norm {norm:.6f})')
    return Rotation.from_quat(q / norm).as_matrix()


def matrix_to_quaternion(R):
    """Return the quaternion ``(x, y, z, w)`` of a rotation matrix, with ``w >= 0``."""
    q = Rotation.from_matrix(validate_rotation(R)).as_quat()
    return q if q[3] >= 0.0 else -q


def pose_from_xyzabc(x, y, z, a, b, c):
    """Return ``T`` (4, 4) from the Mover6 report's goal form X Y Z [m] A B C [rad] (ZYX Euler)."""
    return make_transform([x, y, z], euler_zyx_to_matrix(a, b, c))


def rotation_angle_between(R_a, R_b):
    """Return the angle [rad] of the rotation taking ``R_a`` to ``R_b`` (0 .. pi)."""
    # Rotation.magnitude is accurate near zero, where arccos of the trace loses half the digits.
    R = np.asarray(R_a).T @ np.asarray(R_b)
    return float(Rotation.from_matrix(R).magnitude())


def pose_error(T_a, T_b):
    """Return (position error [m], orientation error [rad]) between two poses."""
    T_a = np.asarray(T_a)
    T_b = np.asarray(T_b)
    return (float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])),
            rotation_angle_between(T_a[:3, :3], T_b[:3, :3]))
