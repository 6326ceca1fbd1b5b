"""
The numeric IK's first start on its own: Levenberg-Marquardt from ``q0``, FK on Python floats.

``ik_numeric`` runs its starts side by side as one batch of arrays. Most poses are solved by
the first start, ``q0`` (a warm start: the current joints, the previous waypoint) within a few
steps, and for one start the arrays' set-up costs more than the arithmetic. ``first_start``
takes the batch's steps for that start alone: the pose and the analytic (geometric) Jacobian
from one pass over the product of exponentials on floats, the error-damped step
``(J^T W J + (c E + lambda_0) I) dq = J^T W e`` (a 6 x 6 solve), the same active set at the
joint limits, the same clipping and wrapping. It gives up (None) when the start stalls as the
batch would re-seed it, and ``ik_numeric`` then runs its batch.
"""

from __future__ import annotations

from functools import lru_cache
import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

# The 3 x 3 identity, row-major.
IDENTITY_ROWS = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def _skew(w):
    """Return the cross-product matrix of ``w`` row-major (9)."""
    return (0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)


def _matmul(a, b):
    """Return the product of two 3x3 matrices, row-major (9 each)."""
    return [a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8], a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
            a[3] * b[1] + a[4] * b[4] + a[5] * b[7], a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8]]


def _apply(a, v):
    """Return the 3x3 matrix ``a`` (9) times ``v`` (3)."""
    return (a[0] * v[0] + a[1] * v[1] + a[2] * v[2], a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
            a[6] * v[0] + a[7] * v[1] + a[8] * v[2])


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _screws(arm: ArmModel) -> tuple:
    """Return per joint (omega, r, K, K^2) and the tip (rotation (9), position (3)) at q = 0."""
    from mover6_control.kinematics.ik_numeric import screw_chain

    chain = screw_chain(arm)
    joints = []
    for axis_point in chain.axis_point:
        omega, r = tuple(axis_point[:3, 0].tolist()), tuple(axis_point[:3, 1].tolist())
        K = np.array(_skew(omega)).reshape(3, 3)
        joints.append((omega, r, tuple(K.reshape(-1).tolist()),
                       tuple((K @ K).reshape(-1).tolist())))
    return tuple(joints), chain.M[:3, :3].reshape(-1).tolist(), tuple(chain.M[:3, 3].tolist())


def residual(arm: ArmModel, q: list, R_goal: list, p_goal: tuple) -> tuple:
    """
    Return the error ``[p_goal - p; log(R_goal R^T)]`` (6 floats) and the Jacobian (6, n).

    The Jacobian is the geometric one (rows [v; w], base frame), as ``pose_residual_batch``'s.
    ``R_goal`` is row-major (9). One pass over the joints carries the frame (rotation R,
    position p) of the product of exponentials: joint i's axis is ``R omega_i`` through
    ``R r_i + p``, and its turn moves points by ``x -> turn (x - r_i) + r_i``.
    """
    joints, tip_R, tip_p = _screws(arm)
    R, p0, p1, p2 = IDENTITY_ROWS, 0.0, 0.0, 0.0
    axes, points = [], []
    for (omega, r, K, KK), angle in zip(joints, q):
        r0, r1, r2 = r
        axes.append(_apply(R, omega))
        points.append((R[0] * r0 + R[1] * r1 + R[2] * r2 + p0,
                       R[3] * r0 + R[4] * r1 + R[5] * r2 + p1,
                       R[6] * r0 + R[7] * r1 + R[8] * r2 + p2))
        s, c = math.sin(angle), 1.0 - math.cos(angle)
        turn = [e + s * x + c * y for e, x, y in zip(IDENTITY_ROWS, K, KK)]
        d0 = r0 - (turn[0] * r0 + turn[1] * r1 + turn[2] * r2)
        d1 = r1 - (turn[3] * r0 + turn[4] * r1 + turn[5] * r2)
        d2 = r2 - (turn[6] * r0 + turn[7] * r1 + turn[8] * r2)
        p0, p1, p2 = (R[0] * d0 + R[1] * d1 + R[2] * d2 + p0,
                      R[3] * d0 + R[4] * d1 + R[5] * d2 + p1,
                      R[6] * d0 + R[7] * d1 + R[8] * d2 + p2)
        R = _matmul(R, turn)
    o = _apply(R, tip_p)
    tip = (o[0] + p0, o[1] + p1, o[2] + p2)
    R = _matmul(R, tip_R)
    g = R_goal
    # R_goal R^T, row-major.
    E = [g[3 * i] * R[3 * j] + g[3 * i + 1] * R[3 * j + 1] + g[3 * i + 2] * R[3 * j + 2]
         for i in range(3) for j in range(3)]
    rot = _log(E)
    J = [[], [], [], [], [], []]
    for z, o in zip(axes, points):
        l0, l1, l2 = tip[0] - o[0], tip[1] - o[1], tip[2] - o[2]
        J[0].append(z[1] * l2 - z[2] * l1)
        J[1].append(z[2] * l0 - z[0] * l2)
        J[2].append(z[0] * l1 - z[1] * l0)
        J[3].append(z[0])
        J[4].append(z[1])
        J[5].append(z[2])
    return [p_goal[0] - tip[0], p_goal[1] - tip[1], p_goal[2] - tip[2]] + rot, J


def _log(E):
    """Return the rotation vector of ``E`` (row-major 9), as ``rotation_log_batch`` does."""
    v = [0.5 * (E[7] - E[5]), 0.5 * (E[2] - E[6]), 0.5 * (E[3] - E[1])]
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    c = 0.5 * (E[0] + E[4] + E[8] - 1.0)
    if c < -0.99 and s < 0.1:           # near a half turn: the batch's careful branch
        from mover6_control.kinematics.ik_numeric import rotation_log_batch

        return rotation_log_batch(np.array(E).reshape(1, 3, 3))[0].tolist()
    scale = math.atan2(s, c) / s if s > 1e-12 else 1.0
    return [x * scale for x in v]


def first_start(arm: ArmModel, T: np.ndarray, q0: np.ndarray, w: np.ndarray, tols: tuple,
                limits: tuple | None, full_turn: np.ndarray | None, damping: float,
                error_damping: float, max_step: float | None, iterations: int,
                stall_iterations: int) -> tuple | None:
    """
    Run the start ``q0`` (n,) alone; return ``(q, pos_err, rot_err, iterations, cost)`` or None.

    ``tols`` (position [m], orientation [rad]); ``limits`` (lo, hi) (n,) each or None;
    ``full_turn`` the joints that wrap. None: the start stalled (the batch would re-seed it)
    or ran out of ``iterations`` before meeting both tolerances. The step's 6 x 6 system is
    solved by numpy; the rest runs on floats.
    """
    n = arm.n_joints
    R_goal, p_goal = T[:3, :3].reshape(-1).tolist(), tuple(T[:3, 3].tolist())
    q = (np.clip(q0, *limits) if limits is not None else np.asarray(q0, dtype=float)).tolist()
    lo, hi = (limits[0].tolist(), limits[1].tolist()) if limits is not None else (None, None)
    wraps = set(full_turn.tolist()) if full_turn is not None else set()
    weights = w.tolist()
    diagonal = np.arange(n) * (n + 1)
    stall_cost, stall_count = math.inf, 0
    for it in range(1, iterations + 1):
        e, J = residual(arm, q, R_goal, p_goal)
        pos2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        rot2 = e[3] * e[3] + e[4] * e[4] + e[5] * e[5]
        cost = sum(wi * ei * ei for wi, ei in zip(weights, e))
        if pos2 < tols[0] ** 2 and rot2 < tols[1] ** 2:
            return np.array(q), math.sqrt(pos2), math.sqrt(rot2), it, cost
        mu = error_damping * 0.5 * cost + damping
        J = np.array(J)
        e = np.array(e)
        dq = _step(J, e, w, mu, diagonal)
        if lo is not None:
            # Active set: a joint at a limit that the step pushes outwards is held there.
            blocked = [j not in wraps and ((q[j] <= lo[j] and dq[j] < 0.0)
                                           or (q[j] >= hi[j] and dq[j] > 0.0)) for j in range(n)]
            if any(blocked):
                dq = _step(J * ~np.array(blocked), e, w, mu, diagonal)
        if max_step is not None:
            top = max(abs(d) for d in dq)
            dq = [d * min(1.0, max_step / (top + 1e-300)) for d in dq]
        q = [qj + dj for qj, dj in zip(q, dq)]
        for j in wraps:
            q[j] = lo[j] + (q[j] - lo[j]) % (2.0 * math.pi)
        if lo is not None:
            q = [min(max(qj, lj), hj) for qj, lj, hj in zip(q, lo, hi)]
        if cost < 0.99 * stall_cost:
            stall_cost, stall_count = cost, 0
        else:
            stall_count += 1
            if stall_count >= stall_iterations:
                return None
    return None


def _step(J, e, w, mu, diagonal):
    """Return ``dq`` (list) of ``(J^T W J + mu I) dq = J^T W e`` for ``J`` (6, n), ``e`` (6,)."""
    JtW = J.T * w
    A = JtW @ J
    A.flat[diagonal] += mu
    return np.linalg.solve(A, JtW @ e).tolist()
