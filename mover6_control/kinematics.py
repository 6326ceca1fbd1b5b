"""Forward kinematics of an ``ArmModel``: single and batched."""

import numpy as np


def axis_rotations(axes, q):
    """Return rotation matrices (..., n, 3, 3) about unit ``axes`` (n, 3) by ``q`` (..., n)."""
    q = np.asarray(q, dtype=float)
    c = np.cos(q)[..., None, None]
    s = np.sin(q)[..., None, None]
    k = axes
    K = np.zeros(axes.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
    K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
    # Rodrigues: R = I + sin K + (1 - cos) K^2
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def fk_frames_batch(arm, Q):
    """
    Return the frame of every joint and the tip, (m, n + 1, 4, 4), for configurations (m, n).

    Frame i (i < n) is joint i's frame after its rotation; frame n is the tip link.
    """
    Q = np.asarray(Q, dtype=float)
    m, n = Q.shape
    R = axis_rotations(arm.axes, Q)              # (m, n, 3, 3)
    frames = np.empty((m, n + 1, 4, 4))
    T = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
    for i in range(n):
        T = T @ arm.origins[i]
        T[:, :3, :3] = T[:, :3, :3] @ R[:, i]
        frames[:, i] = T
    frames[:, n] = T @ arm.tool
    return frames


def fk_batch(arm, Q):
    """Return ``T_base_tip`` (m, 4, 4) for configurations ``Q`` (m, n) [rad]."""
    return fk_frames_batch(arm, Q)[:, -1]


def fk(arm, q):
    """Return ``T_base_tip`` (4, 4) for one configuration ``q`` (n,) [rad]."""
    q = arm.check_q(q)
    return fk_batch(arm, q[None, :])[0]


def fk_frames(arm, q):
    """Return every joint frame and the tip frame (n + 1, 4, 4) for ``q`` (n,) [rad]."""
    q = arm.check_q(q)
    return fk_frames_batch(arm, q[None, :])[0]
