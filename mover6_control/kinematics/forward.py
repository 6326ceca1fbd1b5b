"""
Forward and velocity kinematics of an ``ArmModel``: poses, Jacobian, rates, statics.

Twist ordering: every twist, Jacobian row block and wrench here is ``[linear; angular]``, all in
the base frame. ``J = jacobian(arm, q)`` (6, n) maps joint rates ``qd`` [rad/s] to
``[v; w]`` where ``v`` [m/s] is the velocity of the tip-link origin and ``w`` [rad/s] the
angular velocity (the miniBOT report's ``eta = (v, omega)``). A wrench is ``[f; m]``: force [N] at
the tip-link origin and moment [N m], so the joint torques that balance it are ``J^T [f; m]`` (the
Jacobians and trajectories report, eq. 20).
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_finite_array
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel


def _skew4(axis):
    """Return 4x4 matrices ``K`` and ``K @ K`` of the cross-product matrix of ``axis`` (3,)."""
    K = np.zeros((4, 4))
    K[0, 1], K[0, 2] = -axis[2], axis[1]
    K[1, 0], K[1, 2] = axis[2], -axis[0]
    K[2, 0], K[2, 1] = -axis[1], axis[0]
    return K, K @ K


_CHUNK = 4096  # samples per block: keeps the working set in cache
_TOP = np.eye(4)[:3]  # the top rows of the identity
_TOP.setflags(write=False)
# a x b = a[_NEXT] b[_LAST] - a[_LAST] b[_NEXT]
_NEXT, _LAST = np.array([1, 2, 0]), np.array([2, 0, 1])


def _aligned_axis(axis):
    """Return (j, sign) when ``axis`` is +-e_j (the usual case), else None."""
    j = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[j]) - 1.0) < 1e-15:
        return j, float(np.sign(axis[j]))
    return None


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _steps(arm: ArmModel) -> tuple:
    """
    Return, per joint, what ``_turn`` needs, prepared once per arm.

    ``(O, a, b, sign)`` for an axis +-e_j: a rotation that mixes the columns a and b; or
    ``(O, O K, O K^2, None)`` for any other axis (Rodrigues), with ``O`` the joint's origin.
    """
    steps = []
    for origin, axis in zip(arm.origins, arm.axes):
        aligned = _aligned_axis(axis)
        if aligned is not None:
            j, sign = aligned
            steps.append((origin, (j + 1) % 3, (j + 2) % 3, sign))
        else:
            K, KK = _skew4(axis)
            steps.append((origin, origin @ K, origin @ KK, None))
    return tuple(steps)


def _turn(T, step, s, c):
    """
    Return the top rows (..., 3, 4) of ``T O Rot(k, q)`` for frames ``T`` (..., 3, 4).

    ``s`` and ``c`` are sin(q) and cos(q): floats for one frame, (m, 1) for m frames. ``T O``
    is one (3m, 4) x (4, 4) product. A rotation about a coordinate axis e_j mixes two columns:
    ``(a, b) <- (c a + s b, c b - s a)`` for the two other axes. Any other axis uses Rodrigues,
    ``T O Rot(k, q) = T O + sin(q) T (O K) + (1 - cos(q)) T (O K^2)``.
    """
    O, a, b, sign = step
    shape = T.shape
    flat = T.reshape(-1, 4)
    if sign is None:
        s, c = np.asarray(s)[..., None], np.asarray(c)[..., None]
        return ((flat @ O).reshape(shape) + s * (flat @ a).reshape(shape)
                + (1.0 - c) * (flat @ b).reshape(shape))
    T = (flat @ O).reshape(shape)
    s = s * sign
    col_a, col_b = T[..., a], T[..., b]
    T[..., a], T[..., b] = col_a * c + col_b * s, col_b * c - col_a * s
    return T


def _chain(arm, Q, keep_frames):
    """
    Multiply out the chain for configurations ``Q`` (m, n): frames (m, n + 1, 4, 4) or tips.

    Vectorised without per-sample matrix products (``_turn`` on blocks of samples); only the top
    3 rows are carried.
    """
    Q = as_finite_array(Q, (None, arm.n_joints), 'configurations')
    m, n = Q.shape
    out = np.zeros((m, n + 1, 4, 4) if keep_frames else (m, 4, 4))
    out[..., 3, 3] = 1.0
    steps = _steps(arm)
    for lo in range(0, m, _CHUNK):
        q = Q[lo:lo + _CHUNK]
        k = len(q)
        s = np.sin(q)
        c = np.cos(q)
        T = np.broadcast_to(np.eye(4)[:3], (k, 3, 4))
        for i in range(n):
            T = _turn(T, steps[i], s[:, i, None], c[:, i, None])
            if keep_frames:
                out[lo:lo + k, i, :3] = T
        tip = (T.reshape(-1, 4) @ arm.tool).reshape(k, 3, 4)
        if keep_frames:
            out[lo:lo + k, n, :3] = tip
        else:
            out[lo:lo + k, :3] = tip
    return out


def _frames(arm, q):
    """
    Return the frames (n + 1, 4, 4) of one checked configuration ``q`` (n,): the fast path.

    The batched product's steps on one (3, 4) frame, without its per-call set-up (blocks,
    broadcasting), which costs more than the arithmetic for one configuration.
    """
    n = len(q)
    s = np.sin(q).tolist()
    c = np.cos(q).tolist()
    out = np.zeros((n + 1, 4, 4))
    out[:, 3, 3] = 1.0
    T = _TOP
    for i, step in enumerate(_steps(arm)):
        T = _turn(T, step, s[i], c[i])
        out[i, :3] = T
    out[n, :3] = T @ arm.tool
    return out


def _jacobian_of_frames(frames, axes):
    """
    Return the geometric Jacobians (..., 6, n) of frames (..., n + 1, 4, 4) from ``fk_frames``.

    Column i is ``[z_i x (p_tip - o_i); z_i]`` with ``z_i`` joint i's unit axis ``axes[i]`` and
    ``o_i`` its frame's origin, both in the base frame.
    """
    n = len(axes)
    z = np.einsum('...nij,nj->...ni', frames[..., :n, :3, :3], axes)   # (..., n, 3)
    r = frames[..., n, None, :3, 3] - frames[..., :n, :3, 3]
    J = np.empty(frames.shape[:-3] + (6, n))
    J[..., :3, :] = np.swapaxes(z[..., _NEXT] * r[..., _LAST] - z[..., _LAST] * r[..., _NEXT],
                                -1, -2)                              # z x r
    J[..., 3:, :] = np.swapaxes(z, -1, -2)
    return J


def fk_frames_batch(arm: ArmModel, Q: np.ndarray) -> np.ndarray:
    """
    Return the frame of every joint and the tip, (m, n + 1, 4, 4), for configurations (m, n).

    Frame i (i < n) is joint i's frame after its rotation; frame n is the tip link.
    """
    return _chain(arm, Q, keep_frames=True)


def fk_batch(arm: ArmModel, Q: np.ndarray) -> np.ndarray:
    """Return ``T_base_tip`` (m, 4, 4) for configurations ``Q`` (m, n) [rad]."""
    return _chain(arm, Q, keep_frames=False)


def fk(arm: ArmModel, q: np.ndarray) -> np.ndarray:
    """Return ``T_base_tip`` (4, 4) for one configuration ``q`` (n,) [rad]."""
    return _frames(arm, arm.check_q(q))[-1]


def fk_frames(arm: ArmModel, q: np.ndarray) -> np.ndarray:
    """Return every joint frame and the tip frame (n + 1, 4, 4) for ``q`` (n,) [rad]."""
    return _frames(arm, arm.check_q(q))


def jacobian_batch(arm: ArmModel, Q: np.ndarray) -> np.ndarray:
    """
    Return geometric Jacobians (m, 6, n) in the base frame for configurations ``Q`` (m, n).

    Column i is ``[z_i x (p_tip - o_i); z_i]`` with ``z_i`` joint i's unit axis and ``o_i`` a
    point on it, both in the base frame.
    """
    return _jacobian_of_frames(fk_frames_batch(arm, Q), arm.axes)


def fk_and_jacobian(arm: ArmModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``T_base_tip`` (4, 4) and the geometric Jacobian (6, n) at ``q`` from one pass."""
    frames = _frames(arm, arm.check_q(q))
    return frames[-1], _jacobian_of_frames(frames, arm.axes)


def jacobian(arm: ArmModel, q: np.ndarray) -> np.ndarray:
    """Return the geometric Jacobian (6, n) at ``q`` (n,) [rad]: rows ``[v; w]``, base frame."""
    return fk_and_jacobian(arm, q)[1]


def singular_values(arm: ArmModel, q: np.ndarray) -> np.ndarray:
    """Return the singular values (min(6, n),) of the Jacobian at ``q``, largest first."""
    return np.linalg.svd(jacobian(arm, q), compute_uv=False)


def manipulability(arm: ArmModel, q: np.ndarray) -> float:
    """
    Return Yoshikawa's manipulability at ``q``: the product of the Jacobian's singular values.

    That is ``sqrt(det(J J^T))`` for n >= 6 joints (``sqrt(det(J^T J))`` for fewer); 0 at a
    singularity. Its unit mixes [m] and [rad], so compare it only on one arm.
    """
    return float(np.prod(singular_values(arm, q)))


def condition_number(arm: ArmModel, q: np.ndarray) -> float:
    """
    Return the Jacobian's condition number ``s_max / s_min`` at ``q`` (inf when singular).

    The rows mix [m/s] and [rad/s], so the figure depends on the length unit (metres here), as
    it does in MoveIt Servo, whose thresholds (17 slow down, 30 halt) use the same Jacobian.
    """
    s = singular_values(arm, q)
    return float(s[0] / s[-1]) if s[-1] > 0.0 else float('inf')


def joint_rates(arm: ArmModel, q: np.ndarray, twist: np.ndarray,
                damping: float = 1e-3) -> np.ndarray:
    """
    Return joint rates ``qd`` (n,) [rad/s] that produce ``twist`` = [v; w] [m/s; rad/s].

    Damped least squares: ``qd = J^T (J J^T + damping^2 I)^-1 twist``; ``damping`` = 0 gives
    the Moore-Penrose pseudo-inverse (the miniBOT report's ``pinv(J) @ twist``). Damping keeps the
    rates bounded near a singularity at the price of a small twist error there.
    """
    twist = as_finite_array(twist, (6,), 'twist')
    if not np.isfinite(damping) or damping < 0.0:
        raise InvalidInputError(f'damping must be finite and >= 0, got {damping}')
    J = jacobian(arm, q)
    if damping == 0.0:
        return np.linalg.pinv(J) @ twist
    return J.T @ np.linalg.solve(J @ J.T + damping ** 2 * np.eye(6), twist)


def joint_torques(arm: ArmModel, q: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """
    Return joint torques ``tau = J^T wrench`` (n,) [N m] at ``q`` [rad].

    ``wrench`` (6,) is ``[f; m]``: force [N] acting at the tip-link origin and moment [N m], both
    in the base frame. These are the torques the joints must exert to hold the arm against that
    wrench applied by the arm on its environment (or to balance ``-wrench`` applied on it).
    """
    wrench = as_finite_array(wrench, (6,), 'wrench')
    return jacobian(arm, q).T @ wrench
