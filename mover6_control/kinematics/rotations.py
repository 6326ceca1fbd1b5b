"""
Rotations and homogeneous transforms: validation and conversions.

Conventions:
- A pose is a 4x4 homogeneous transform ``T_base_tool`` [m].
- Euler angles follow the Mover6 report (MATLAB's default ZYX): ``R = Rz(A) @ Ry(B) @ Rx(C)``, so A
  is yaw, B pitch and C roll [rad].
- Quaternions are in ROS order ``(x, y, z, w)``.

The conversions are closed forms in numpy (the quaternion of a matrix by the largest of its
trace and diagonal, as scipy's ``Rotation.from_matrix`` takes it): no ``scipy.spatial``, which
took half a second of every node's start-up to import; the tests check them against scipy.
"""

from collections.abc import Sequence
import math

from mover6_control.errors import QuaternionError
from mover6_control.validation import as_finite_array
from mover6_control.values import check_rotation_rows, QUATERNION_NORM_TOL, ToolPose
import numpy as np


def validate_rotation(R: np.ndarray, name: str = 'rotation') -> np.ndarray:
    """Check that ``R`` is a finite 3x3 proper rotation matrix and return it as an array."""
    R = as_finite_array(R, (3, 3), name)
    check_rotation_rows(R.tolist(), name)
    return R


def validate_transform(T: object, name: str = 'transform') -> np.ndarray:
    """
    Return the matrix (4, 4) of ``T``: a ``ToolPose`` as it is, else checked by ``ToolPose``.

    For raw input a caller hands the library; a ``ToolPose`` was checked where it was made.
    """
    return ToolPose.of(T, name).matrix


def make_transform(position: Sequence[float], R: np.ndarray | None = None) -> np.ndarray:
    """Build ``T`` (4, 4) from a position (3,) [m] and a rotation matrix (3, 3)."""
    T = np.eye(4)
    T[:3, 3] = as_finite_array(position, (3,), 'position')
    if R is not None:
        T[:3, :3] = validate_rotation(R)
    return T


def euler_zyx_to_matrix(a: float, b: float, c: float) -> np.ndarray:
    """Return ``Rz(a) @ Ry(b) @ Rx(c)`` (3, 3) for angles [rad] in MATLAB's default ZYX order."""
    a, b, c = as_finite_array([a, b, c], (3,), 'euler angles')
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    return np.array([[ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
                     [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
                     [-sb, cb * sc, cb * cc]])


def matrix_to_euler_zyx(R: np.ndarray) -> tuple[float, float, float]:
    """Return (A, B, C) [rad] with ``R = Rz(A) Ry(B) Rx(C)``; B in [-pi/2, pi/2]."""
    R = validate_rotation(R)
    return euler_zyx_closed_form(R)


def quaternion_to_matrix(q_xyzw: Sequence[float]) -> np.ndarray:
    """
    Return the rotation matrix of a quaternion ``(x, y, z, w)``; rejects a zero quaternion.

    A quaternion whose norm is off 1 by more than ``QUATERNION_NORM_TOL`` is rejected too,
    because a sender that means a rotation normalises it; silently normalising would hide a bug
    upstream.
    """
    q = as_finite_array(q_xyzw, (4,), 'quaternion')
    norm = float(np.linalg.norm(q))
    if norm < 1e-9:
        raise QuaternionError('quaternion is zero: it describes no rotation')
    if abs(norm - 1.0) > QUATERNION_NORM_TOL:
        raise QuaternionError(f'quaternion is not unit length (norm {norm:.6f})')
    return unit_quaternion_to_matrix(q / norm)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Return the quaternion ``(x, y, z, w)`` of a rotation matrix, with ``w >= 0``."""
    return matrices_to_quaternions(validate_rotation(R))


def matrices_to_quaternions(R: np.ndarray) -> np.ndarray:
    """
    Return the quaternions ``(..., 4)`` ``(x, y, z, w)``, ``w >= 0``, of rotations ``(..., 3, 3)``.

    For matrices known to be rotations (``matrix_to_quaternion`` checks one first). Each comes
    from the largest of the trace and the diagonal entries, so no division is by a small number.
    """
    R = np.asarray(R, dtype=float)
    if R.ndim == 2:
        return _matrix_to_quaternion(R.tolist())
    # One matrix at a time: the callers pass a few (SLERP's keys), and in plain floats one
    # conversion takes a fraction of numpy's per-call overhead (the state publisher's /tf).
    flat = R.reshape(-1, 3, 3).tolist()
    return np.array([_matrix_to_quaternion(m) for m in flat]).reshape(R.shape[:-2] + (4,))


def _matrix_to_quaternion(R: list) -> np.ndarray:
    """Return the quaternion (4,) of one rotation given as nested lists (see the caller)."""
    trace = R[0][0] + R[1][1] + R[2][2]
    diagonal = (R[0][0], R[1][1], R[2][2])
    i = max(range(3), key=diagonal.__getitem__)
    if trace > diagonal[i]:       # as argmax: the first of equals, the trace last
        q = [R[2][1] - R[1][2], R[0][2] - R[2][0], R[1][0] - R[0][1], 1.0 + trace]
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        q = [0.0, 0.0, 0.0, R[k][j] - R[j][k]]
        q[i] = 1.0 - trace + 2.0 * R[i][i]
        q[j] = R[j][i] + R[i][j]
        q[k] = R[k][i] + R[i][k]
    norm = math.sqrt(sum(v * v for v in q))
    sign = -1.0 if q[3] < 0.0 else 1.0
    return np.array([sign * v / norm for v in q])


def unit_quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Return the rotations ``(..., 3, 3)`` of unit quaternions ``(..., 4)`` ``(x, y, z, w)``."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def quaternion_angle(q: np.ndarray) -> np.ndarray:
    """Return the rotation angle [rad] (0 .. pi) of unit quaternions ``(..., 4)``."""
    q = np.asarray(q, dtype=float)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., :3], axis=-1), np.abs(q[..., 3]))


def slerp(keys: Sequence[float], R_keys: np.ndarray, params: Sequence[float]) -> np.ndarray:
    """
    Return the rotations ``(m, 3, 3)`` at ``params`` (m,), SLERPed between ``R_keys`` (k, 3, 3).

    ``keys`` (k,) rise strictly; a parameter outside them takes the nearest end's rotation.
    Between two keys the rotation turns about one fixed axis at a constant rate, the shorter
    way, as scipy's ``Slerp`` does.
    """
    keys = np.asarray(keys, dtype=float)
    q = matrices_to_quaternions(R_keys)
    params = np.clip(np.asarray(params, dtype=float), keys[0], keys[-1])
    seg = np.clip(np.searchsorted(keys, params, side='right') - 1, 0, len(keys) - 2)
    u = (params - keys[seg]) / (keys[seg + 1] - keys[seg])
    q0, q1 = q[seg], q[seg + 1]
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[:, None] < 0.0, -q1, q1)            # the shorter way
    angle = np.arccos(np.clip(np.abs(dot), -1.0, 1.0))
    small = angle < 1e-9
    sin = np.where(small, 1.0, np.sin(angle))
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * angle) / sin)
    w1 = np.where(small, u, np.sin(u * angle) / sin)
    out = w0[:, None] * q0 + w1[:, None] * q1
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return unit_quaternion_to_matrix(out)


def pose_from_xyzabc(x: float, y: float, z: float, a: float, b: float, c: float) -> np.ndarray:
    """Return ``T`` (4, 4) from the Mover6 report's goal form X Y Z [m] A B C [rad] (ZYX Euler)."""
    return make_transform([x, y, z], euler_zyx_to_matrix(a, b, c))


def goal_relative_to_start(T_start: np.ndarray, x: float, y: float, z: float, a: float,
                           b: float, c: float) -> np.ndarray:
    """
    Return the goal pose as the Mover6 report's MATLAB builds it, rotation relative to the start.

    Position X Y Z [m] is absolute; the rotation is ``R_start @ Rz(a) Ry(b) Rx(c)``, so
    ``a = b = c = 0`` keeps the start orientation (the Mover6 report:
    ``tform2rotm(initial_Pos) * eul2rotm([A, B, C])``).
    """
    T_start = validate_transform(T_start, 'T_start')
    return make_transform([x, y, z], T_start[:3, :3] @ euler_zyx_to_matrix(a, b, c))


def rotation_angle_between(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Return the angle [rad] of the rotation taking ``R_a`` to ``R_b`` (0 .. pi)."""
    # From the quaternion: accurate near zero, where arccos of the trace loses half the digits.
    R = np.asarray(R_a).T @ np.asarray(R_b)
    return float(quaternion_angle(matrices_to_quaternions(R)))


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """Return (position error [m], orientation error [rad]) between two poses."""
    T_a = np.asarray(T_a)
    T_b = np.asarray(T_b)
    return (float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3])),
            rotation_angle_between(T_a[:3, :3], T_b[:3, :3]))


# Below this |cos B| the ZYX angles are at gimbal lock: only A - C (B = +pi/2) or A + C
# (B = -pi/2) is defined, and C is set to 0.
GIMBAL_LOCK_TOL = 1e-9


def euler_zyx_closed_form(R):
    """
    Return (A, B, C) [rad] with ``R = Rz(A) Ry(B) Rx(C)`` in closed form; B in [-pi/2, pi/2].

    Unlike scipy's ``as_euler`` it prints no warning at gimbal lock (B = +-pi/2, the Mover6's
    home orientation): there it returns the deterministic split C = 0, which gives back ``R``.
    """
    R = np.asarray(R, dtype=float)
    cos_b = float(np.hypot(R[0, 0], R[1, 0]))
    b = float(np.arctan2(-R[2, 0], cos_b))
    if cos_b > GIMBAL_LOCK_TOL:
        a = float(np.arctan2(R[1, 0], R[0, 0]))
        c = float(np.arctan2(R[2, 1], R[2, 2]))
    else:
        b = float(np.copysign(np.pi / 2, -R[2, 0]))
        a = float(np.arctan2(-R[0, 1], R[1, 1]))
        c = 0.0
    return a, b, c


def _near(angle, ref):
    """Return ``angle`` plus the multiple of 2 pi that brings it nearest ``ref`` [rad]."""
    return float(angle + 2.0 * np.pi * np.round((ref - angle) / (2.0 * np.pi)))


def euler_zyx_near(R, ref, lock_tol=GIMBAL_LOCK_TOL):
    """
    Return the (A, B, C) [rad] of ``R = Rz(A) Ry(B) Rx(C)`` nearest the angles ``ref`` (3,).

    Every rotation has two ZYX triples, (A, B, C) and (A + pi, pi - B, C + pi), each up to
    multiples of 2 pi; this picks the one nearest ``ref`` (say the angles a user typed), so a
    goal typed with B = 1.5708 is not printed back as (pi, 1.5707926, pi). Where ``|cos B| <=
    lock_tol`` (gimbal lock) B is taken as +-pi/2 and only A - C (B = pi/2) or A + C
    (B = -pi/2) is defined: the split nearest ``ref`` is returned, deterministic, and off the
    exact angles by at most about ``lock_tol`` [rad].
    """
    R = validate_rotation(R)
    ref_a, ref_b, ref_c = (float(v) for v in as_finite_array(ref, (3,), 'ref'))
    if float(np.hypot(R[0, 0], R[1, 0])) <= lock_tol:
        if R[2, 0] < 0.0:        # B = pi/2: R depends on C - A only
            diff = _near(float(np.arctan2(R[0, 1], R[1, 1])), ref_c - ref_a)
            k = diff - (ref_c - ref_a)
            return ref_a - k / 2.0, _near(np.pi / 2, ref_b), ref_c + k / 2.0
        total = _near(float(np.arctan2(-R[0, 1], R[1, 1])), ref_a + ref_c)   # B = -pi/2: A + C
        k = total - (ref_a + ref_c)
        return ref_a + k / 2.0, _near(-np.pi / 2, ref_b), ref_c + k / 2.0
    a, b, c = euler_zyx_closed_form(R)
    best = None
    for cand in ((a, b, c), (a + np.pi, np.pi - b, c + np.pi)):
        cand = tuple(_near(v, r) for v, r in zip(cand, (ref_a, ref_b, ref_c)))
        dist = (cand[0] - ref_a) ** 2 + (cand[1] - ref_b) ** 2 + (cand[2] - ref_c) ** 2
        if best is None or dist < best[0]:
            best = (dist, cand)
    return best[1]


def rotation_log_batch(R: np.ndarray) -> np.ndarray:
    """
    Return rotation vectors (..., 3) [rad] of rotation matrices (..., 3, 3).

    Accurate near zero (uses the skew part) and at pi (uses the symmetric part).
    """
    v = np.empty(R.shape[:-1])
    v[..., 0] = R[..., 2, 1] - R[..., 1, 2]
    v[..., 1] = R[..., 0, 2] - R[..., 2, 0]
    v[..., 2] = R[..., 1, 0] - R[..., 0, 1]
    v *= 0.5
    s = np.sqrt((v * v).sum(-1))
    c = 0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0)
    angle = np.arctan2(s, c)
    scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 1.0)
    out = v * scale[..., None]
    if c.min() < -0.99:
        near_pi = (c < -0.99) & (s < 0.1)
        # angle ~ pi: the axis from the largest column of a a^T = (sym(R) - c I) / (1 - c).
        Rn, cn = R[near_pi], c[near_pi, None, None]
        B = (0.5 * (Rn + Rn.transpose(0, 2, 1)) - cn * np.eye(3)) / (1.0 - cn)
        idx = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        axis = B[np.arange(len(B)), :, idx]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        sign = np.where(np.einsum('ki,ki->k', axis, v[near_pi]) < 0.0, -1.0, 1.0)
        out[near_pi] = axis * (sign * angle[near_pi])[:, None]
    return out
