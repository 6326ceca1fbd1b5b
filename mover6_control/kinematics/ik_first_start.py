"""
The numeric IK's first start on its own: Levenberg-Marquardt from ``q0``, FK on Python floats.

``ik_numeric`` runs its starts side by side as one batch of arrays. Most poses are solved by
the first start, ``q0`` (a warm start: the current joints, the previous waypoint) within a few
steps, and for one start the arrays' set-up costs more than the arithmetic. ``first_start``
takes the batch's steps for that start alone: the pose and the analytic (geometric) Jacobian
from one pass over the chain on floats (``chain``), the error-damped step
``(J^T W J + (c E + lambda_0) I) dq = J^T W e`` (a 6 x 6 solve), the same active set at the
joint limits, the same clipping and wrapping. It gives up (None) when the start stalls as the
batch would re-seed it, and ``ik_numeric`` then runs its batch.
"""

from __future__ import annotations

from functools import lru_cache
import math
from typing import TYPE_CHECKING

from mover6_control.kinematics.rotations import rotation_log_batch
import numpy as np
from scipy.linalg.lapack import dposv

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

# The 3 x 3 identity, row-major.
IDENTITY_ROWS = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def _signed_permutation(R):
    """Return per column (source column, sign) when ``R`` (3, 3) permutes signed axes, or None."""
    out = []
    for k in range(3):
        j = int(np.argmax(np.abs(R[:, k])))
        # DH tables give cos(pi / 2) = 6e-17 for a zero: entries below 1e-15 count as zeros.
        if abs(abs(R[j, k]) - 1.0) > 1e-15 or np.count_nonzero(np.abs(R[:, k]) > 1e-15) != 1:
            return None
        out.append((j, R[j, k] > 0.0))
    return tuple(out)


def _fixed_step(T):
    """
    Return how to apply the fixed transform ``T`` (4, 4): (offset, permutation, rotation).

    The offset is None when zero; the permutation (signed columns) and the rotation (rows) are
    both None for a translation.
    """
    t = tuple(T[:3, 3].tolist())
    perm = _signed_permutation(T[:3, :3])
    if perm == ((0, True), (1, True), (2, True)):
        return t if any(t) else None, None, None          # a translation
    return (t if any(t) else None, perm, None if perm is not None else T[:3, :3].tolist())


def _turn_step(axis):
    """Return (j, a, b, sign, None) for an axis +-e_j, else (None, .., axis) (Rodrigues)."""
    j = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[j]) - 1.0) < 1e-15:
        return (j, (j + 1) % 3, (j + 2) % 3, 1.0 if axis[j] > 0.0 else -1.0, None)
    return (None, None, None, None, tuple(axis.tolist()))


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _plan(arm: ArmModel) -> tuple:
    """Return per joint its origin's and its turn's steps, and the tool's step, once per arm."""
    joints = tuple(_fixed_step(origin) + (_turn_step(axis),)
                   for origin, axis in zip(arm.origins, arm.axes))
    return joints, _fixed_step(arm.tool)


def _negated(v):
    """Return ``-v`` of a 3-tuple."""
    return (-v[0], -v[1], -v[2])


def _fixed(c, p, t, perm, rot):
    """Return the frame (columns ``c``, origin ``p``) times a fixed transform (``_fixed_step``)."""
    if t is not None:
        t0, t1, t2 = t
        x, y, z = c
        p = (p[0] + x[0] * t0 + y[0] * t1 + z[0] * t2, p[1] + x[1] * t0 + y[1] * t1 + z[1] * t2,
             p[2] + x[2] * t0 + y[2] * t1 + z[2] * t2)
    if rot is None:
        if perm is None:
            return c, p
        (j0, s0), (j1, s1), (j2, s2) = perm
        return [c[j0] if s0 else _negated(c[j0]), c[j1] if s1 else _negated(c[j1]),
                c[j2] if s2 else _negated(c[j2])], p
    (x0, x1, x2), (y0, y1, y2), (z0, z1, z2) = c
    (a, b, d), (e, f, g), (h, i, k) = rot
    return [(x0 * a + y0 * e + z0 * h, x1 * a + y1 * e + z1 * h, x2 * a + y2 * e + z2 * h),
            (x0 * b + y0 * f + z0 * i, x1 * b + y1 * f + z1 * i, x2 * b + y2 * f + z2 * i),
            (x0 * d + y0 * g + z0 * k, x1 * d + y1 * g + z1 * k, x2 * d + y2 * g + z2 * k)], p


def chain(arm: ArmModel, q: list) -> tuple:
    """
    Return the tip's rotation (its columns), its position and each joint's axis and point.

    One pass over the URDF chain on floats: each joint's fixed origin (a signed permutation of
    the axes, the usual case, costs no product), then its turn (about a coordinate axis it mixes
    two columns; any other axis by Rodrigues). Joint i's axis and a point on it are in the base
    frame, as the geometric Jacobian needs them.
    """
    joints, tool = _plan(arm)
    c = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]   # columns of the rotation
    p = (0.0, 0.0, 0.0)
    axes, points = [], []
    for (t, perm, rot, (j, a, b, sign, general)), angle in zip(joints, q):
        if perm is None and rot is None:         # a translation (inline: the usual case)
            if t is not None:
                x, y, z = c
                t0, t1, t2 = t
                p = (p[0] + x[0] * t0 + y[0] * t1 + z[0] * t2,
                     p[1] + x[1] * t0 + y[1] * t1 + z[1] * t2,
                     p[2] + x[2] * t0 + y[2] * t1 + z[2] * t2)
        else:
            c, p = _fixed(c, p, t, perm, rot)
        points.append(p)
        s, co = math.sin(angle), math.cos(angle)
        if j is not None:
            axes.append(c[j] if sign > 0.0 else _negated(c[j]))
            s *= sign
            ca, cb = c[a], c[b]
            c[a] = (ca[0] * co + cb[0] * s, ca[1] * co + cb[1] * s, ca[2] * co + cb[2] * s)
            c[b] = (cb[0] * co - ca[0] * s, cb[1] * co - ca[1] * s, cb[2] * co - ca[2] * s)
            continue
        k0, k1, k2 = general
        z = tuple(c[0][i] * k0 + c[1][i] * k1 + c[2][i] * k2 for i in range(3))
        axes.append(z)
        o = 1.0 - co            # R Rot(k, q) = Rot(R k, q) R: each column turns about z
        turned = []
        for v in c:
            d = (z[0] * v[0] + z[1] * v[1] + z[2] * v[2]) * o
            turned.append((v[0] * co + (z[1] * v[2] - z[2] * v[1]) * s + z[0] * d,
                           v[1] * co + (z[2] * v[0] - z[0] * v[2]) * s + z[1] * d,
                           v[2] * co + (z[0] * v[1] - z[1] * v[0]) * s + z[2] * d))
        c = turned
    c, tip = _fixed(c, p, *tool)
    return c, tip, axes, points


def _error(c, tip, R_goal, p_goal):
    """Return ``[p_goal - p; log(R_goal R^T)]`` for the tip's columns ``c`` and position."""
    g = R_goal
    x, y, z = c
    # R_goal R^T: row i of R_goal against row j of R (R[j][k] = c[k][j]).
    E = [g[i] * x[j] + g[i + 1] * y[j] + g[i + 2] * z[j] for i in (0, 3, 6) for j in range(3)]
    return [p_goal[0] - tip[0], p_goal[1] - tip[1], p_goal[2] - tip[2]] + _log(E)


def _jacobian(tip, axes, points):
    """Return the geometric Jacobian (6, n) as lists, rows [v; w], from the joints' axes."""
    t0, t1, t2 = tip
    J = [[], [], [], [], [], []]
    v0, v1, v2, w0, w1, w2 = J
    for z, o in zip(axes, points):
        l0, l1, l2 = t0 - o[0], t1 - o[1], t2 - o[2]
        v0.append(z[1] * l2 - z[2] * l1)
        v1.append(z[2] * l0 - z[0] * l2)
        v2.append(z[0] * l1 - z[1] * l0)
        w0.append(z[0])
        w1.append(z[1])
        w2.append(z[2])
    return J


def residual(arm: ArmModel, q: list, R_goal: list, p_goal: tuple) -> tuple:
    """
    Return the error ``[p_goal - p; log(R_goal R^T)]`` (6 floats) and the Jacobian (6, n).

    The Jacobian is the geometric one (rows [v; w], base frame), as ``pose_residual_batch``'s.
    ``R_goal`` is row-major (9). One pass over the chain (``chain``).
    """
    c, tip, axes, points = chain(arm, q)
    return _error(c, tip, R_goal, p_goal), _jacobian(tip, axes, points)


def _log(E):
    """Return the rotation vector of ``E`` (row-major 9), as ``rotation_log_batch`` does."""
    v = [0.5 * (E[7] - E[5]), 0.5 * (E[2] - E[6]), 0.5 * (E[3] - E[1])]
    s = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    c = 0.5 * (E[0] + E[4] + E[8] - 1.0)
    if c < -0.99 and s < 0.1:           # near a half turn: the batch's careful branch
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
    or ran out of ``iterations`` before meeting both tolerances. The Jacobian is built only
    when the tolerances do not hold yet; the step's 6 x 6 system is solved by LAPACK's
    Cholesky (``dposv``); the rest runs on floats.
    """
    n = arm.n_joints
    R_goal, p_goal = T[:3, :3].reshape(-1).tolist(), tuple(T[:3, 3].tolist())
    q = np.asarray(q0, dtype=float).tolist()
    lo, hi = (limits[0].tolist(), limits[1].tolist()) if limits is not None else (None, None)
    wraps = full_turn.tolist() if full_turn is not None else []
    at_limit = False
    if lo is not None:
        q, at_limit = _clip(q, lo, hi)
    weights = w.tolist()
    w0, w1, w2, w3, w4, w5 = weights
    root_w = [math.sqrt(x) for x in weights]
    pos_tol2, rot_tol2 = tols[0] ** 2, tols[1] ** 2
    stall_cost, stall_count = math.inf, 0
    for it in range(1, iterations + 1):
        c, tip, axes, points = chain(arm, q)
        e = _error(c, tip, R_goal, p_goal)
        e0, e1, e2, e3, e4, e5 = e
        pos2 = e0 * e0 + e1 * e1 + e2 * e2
        rot2 = e3 * e3 + e4 * e4 + e5 * e5
        cost = w0 * e0 * e0 + w1 * e1 * e1 + w2 * e2 * e2 + w3 * e3 * e3 + w4 * e4 * e4 \
            + w5 * e5 * e5
        if pos2 < pos_tol2 and rot2 < rot_tol2:
            return np.array(q), math.sqrt(pos2), math.sqrt(rot2), it, cost
        mu = error_damping * 0.5 * cost + damping
        M = np.array(_weighted_columns(tip, axes, points, e, root_w)).T
        dq = _step(M, mu)
        if at_limit:
            # Active set: a joint at a limit that the step pushes outwards is held there.
            blocked = [j not in wraps and ((q[j] <= lo[j] and dq[j] < 0.0)
                                           or (q[j] >= hi[j] and dq[j] > 0.0)) for j in range(n)]
            if True in blocked:
                M[:, :n] *= ~np.array(blocked)
                dq = _step(M, mu)
        if max_step is not None:
            top = max(abs(d) for d in dq)
            dq = [d * min(1.0, max_step / (top + 1e-300)) for d in dq]
        q = [qj + dj for qj, dj in zip(q, dq)]
        for j in wraps:
            q[j] = lo[j] + (q[j] - lo[j]) % (2.0 * math.pi)
        if lo is not None:
            q, at_limit = _clip(q, lo, hi)
        if cost < 0.99 * stall_cost:
            stall_cost, stall_count = cost, 0
        else:
            stall_count += 1
            if stall_count >= stall_iterations:
                return None
    return None


def _weighted_columns(tip, axes, points, e, root_w):
    """
    Return the columns of ``W^(1/2) [J | e]``: n + 1 tuples of 6.

    Its Gram matrix holds ``J^T W J`` and ``J^T W e`` (J the geometric Jacobian, as
    ``_jacobian``).
    """
    t0, t1, t2 = tip
    r0, r1, r2, r3, r4, r5 = root_w
    out = []
    for z, o in zip(axes, points):
        l0, l1, l2 = t0 - o[0], t1 - o[1], t2 - o[2]
        z0, z1, z2 = z
        out.append((r0 * (z1 * l2 - z2 * l1), r1 * (z2 * l0 - z0 * l2), r2 * (z0 * l1 - z1 * l0),
                    r3 * z0, r4 * z1, r5 * z2))
    out.append((r0 * e[0], r1 * e[1], r2 * e[2], r3 * e[3], r4 * e[4], r5 * e[5]))
    return out


def _clip(q, lo, hi):
    """Return ``q`` clipped to [lo, hi] (lists) and whether any joint sits on a limit."""
    out = [lj if qj < lj else hj if qj > hj else qj for qj, lj, hj in zip(q, lo, hi)]
    return out, any(qj == lj or qj == hj for qj, lj, hj in zip(out, lo, hi))


def _step(M, mu):
    """
    Return ``dq`` (list) of ``(J^T W J + mu I) dq = J^T W e`` from ``M = W^(1/2) [J | e]``.

    The matrix is symmetric positive definite (mu > 0): Cholesky, with a general solve should
    rounding make it fail.
    """
    n = M.shape[1] - 1
    G = M.T @ M
    A = G[:n, :n]
    A.flat[::n + 1] += mu
    _, x, info = dposv(A, G[:n, n])
    if info != 0:
        x = np.linalg.solve(A, G[:n, n])
    return x.tolist()
