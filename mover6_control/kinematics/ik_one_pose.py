"""
Closed-form IK of one pose on Python floats: the batch solver's steps without its arrays.

``ik_closed_form`` answers one pose at a time (a goal check, a servo step, a reachability
verdict). Through the batch solver (``ik_closed_form_batch``) that costs a few hundred array
operations of one element each; here the same steps (the module docstring of
``kinematics.ik_closed_form``: wrist centre, q1, q3 and q2, then the wrist by Paden-Kahan
subproblems) run on floats, and a branch whose joint falls outside its limits is dropped as
soon as that joint is known (with ``within_limits``), before the joints after it are solved.
Every candidate left is checked by forward kinematics on floats (the product of exponentials),
with the batch solver's tolerance test. The arm's constants are prepared once per arm.
"""

from __future__ import annotations

from functools import lru_cache
import math
from typing import TYPE_CHECKING

from mover6_control.kinematics.ik_first_start import IDENTITY_ROWS
from mover6_control.kinematics.wrist import VERIFY_TOL, wrist_geometry
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

_TWO_PI = 2.0 * math.pi


def _dot(a, b):
    """Return the dot product of two 3-tuples."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    """Return the cross product of two 3-tuples."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _sub(a, b):
    """Return ``a - b`` of two 3-tuples."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _normal(v, w):
    """Return ``v`` without its component along the unit ``w``."""
    d = _dot(v, w)
    return (v[0] - d * w[0], v[1] - d * w[1], v[2] - d * w[2])


def _rotate(w, s, c, v):
    """Rotate ``v`` about the unit ``w`` by the angle of sine ``s``, cosine ``c`` (Rodrigues)."""
    d = _dot(w, v) * (1.0 - c)
    x = _cross(w, v)
    return (v[0] * c + x[0] * s + w[0] * d, v[1] * c + x[1] * s + w[1] * d,
            v[2] * c + x[2] * s + w[2] * d)


def _skew(w):
    """Return the cross-product matrix of ``w`` row-major (9)."""
    return (0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _constants(arm: ArmModel) -> dict:
    """Return the arm's screws and the solver's constants as floats (raises as the closed form)."""
    geo = wrist_geometry(arm)
    w = [tuple(v) for v in geo.omega.tolist()]
    r = [tuple(v) for v in geo.r.tolist()]
    p0 = tuple(geo.wrist_point.tolist())
    M_R = geo.M[:3, :3]
    e = _normal(_sub(r[2], r[1]), w[1])
    u = _normal(_sub(p0, r[2]), w[1])
    n45 = _cross(w[3], w[4])
    s45 = _dot(w[3], w[4])
    up6 = _normal(w[5], w[4])
    x6 = tuple(geo.x6.tolist())
    upx6 = _normal(x6, w[5])
    return {
        'w': w, 'r': r, 'p0': p0, 'wit': tuple(geo.wrist_in_tip.tolist()),
        'g6': tuple((M_R.T @ geo.omega[5]).tolist()), 'gx': tuple((M_R.T @ geo.x6).tolist()),
        's12': _dot(w[0], w[1]), 'c1': _dot(w[1], _sub(p0, r[0])),
        'e': e, 'u': u, 'ee_uu': _dot(e, e) + _dot(u, u), 'eu': _dot(e, u),
        'e_w3u': _dot(e, _cross(w[2], u)), 'p0_r3': _sub(p0, r[2]),
        's45': s45, 's56': _dot(w[4], w[5]), 'n45': n45, 'nn45': _dot(n45, n45),
        'den': s45 * s45 - 1.0, 'up6': up6, 'w5_up6': _cross(w[4], up6),
        'upx6': upx6, 'w6_upx6': _cross(w[5], upx6),
        'lower': arm.lower.tolist(), 'upper': arm.upper.tolist(),
        'tip': tuple(geo.M[:3, 3].tolist()), 'tip_R': M_R.reshape(-1).tolist(),
        'K': [_skew(v) for v in w], 'KK': [tuple((np.array(_skew(v)).reshape(3, 3) @ np.array(
            _skew(v)).reshape(3, 3)).reshape(-1).tolist()) for v in w],
    }


def _cos_sin(a, b, c, tol=1e-12):
    """Return the roots of ``a cos t + b sin t = c`` (two), whether solvable, ``hypot(a, b)``."""
    rho = math.hypot(a, b)
    ok = abs(c) <= rho + tol
    delta = math.acos(min(1.0, max(-1.0, c / (rho if rho > tol else 1.0))))
    phi = math.atan2(b, a)
    return (phi + delta, phi - delta), ok, rho


def ik_one_pose(arm: ArmModel, T, q_ref, within_limits: bool = True,
                tol: float = VERIFY_TOL) -> list:
    """
    Return the verified solutions of the pose ``T`` (4, 4) as lists of 6 floats [rad].

    ``T`` is trusted (``ik_closed_form`` validates it); ``q_ref`` (6 floats) picks the whole
    turn of each angle and q1, q4 at shoulder and wrist singularities. The order is the batch
    solver's branch order; repeats are left in (the caller drops them).
    """
    k = _constants(arm)
    lo, hi = k['lower'], k['upper']

    def alias(j, q):
        ref = q_ref[j]
        q = ref + ((q - ref + math.pi) % _TWO_PI - math.pi)
        if not within_limits:
            return q
        if q < lo[j]:
            up = q + _TWO_PI
            if lo[j] <= up <= hi[j]:
                q = up
        elif q > hi[j]:
            down = q - _TWO_PI
            if lo[j] <= down <= hi[j]:
                q = down
        return q if lo[j] - 1e-9 <= q <= hi[j] + 1e-9 else None

    w1, w2, w3, w4, w5, w6 = k['w']
    r1, r2, r3 = k['r'][:3]
    R = (T[0][:3], T[1][:3], T[2][:3])
    t = (T[0][3], T[1][3], T[2][3])
    wit = k['wit']
    p = tuple(_dot(R[i], wit) + t[i] for i in range(3))
    g6 = tuple(_dot(R[i], k['g6']) for i in range(3))
    gx = tuple(_dot(R[i], k['gx']) for i in range(3))
    # q1: w2 . (Rot(w1, -q1)(p - r1) + r1) = w2 . p0
    v = _sub(p, r1)
    v1 = _dot(v, w1)
    a = _dot(v, w2) - v1 * k['s12']
    b = -_dot(_cross(w1, v), w2)
    q1s, ok1, rho1 = _cos_sin(a, b, k['c1'] - v1 * k['s12'])
    if rho1 < 1e-9:                                    # shoulder singularity
        q1s = (q_ref[0], q_ref[0])
        ok1 = ok1 or abs(k['c1'] - v1 * k['s12']) < 1e-9
    out = []
    if not ok1:
        return out
    for q1 in q1s:
        q1a = alias(0, q1)
        if q1a is None:
            continue
        s1, c1 = math.sin(-q1), math.cos(-q1)
        p1 = _rotate(w1, s1, c1, v)
        p1 = (p1[0] + r1[0], p1[1] + r1[1], p1[2] + r1[2])
        d = _normal(_sub(p1, r2), w2)
        q3s, ok3, _ = _cos_sin(k['eu'], k['e_w3u'], (_dot(d, d) - k['ee_uu']) / 2.0)
        if not ok3:
            continue
        g6_1, gx_1 = _rotate(w1, s1, c1, g6), _rotate(w1, s1, c1, gx)
        target = _sub(p1, r2)
        for q3 in q3s:
            q3a = alias(2, q3)
            if q3a is None:
                continue
            s3, c3 = math.sin(q3), math.cos(q3)
            x = _rotate(w3, s3, c3, k['p0_r3'])
            up = _normal((x[0] + r3[0] - r2[0], x[1] + r3[1] - r2[1], x[2] + r3[2] - r2[2]), w2)
            q2 = math.atan2(_dot(_cross(w2, up), target), _dot(up, target))
            q2a = alias(1, q2)
            if q2a is None:
                continue
            s2, c2 = math.sin(-q2), math.cos(-q2)
            tv = _rotate(w3, -s3, c3, _rotate(w2, s2, c2, g6_1))
            tx = _rotate(w3, -s3, c3, _rotate(w2, s2, c2, gx_1))
            _wrist(k, q_ref, alias, (q1a, q2a, q3a), tv, tx, out)
    return [q for q in out if _reproduces(k, q, R, t, tol)]


def _wrist(k, q_ref, alias, arm_q, tv, tx, out):
    """Append the wrist's branches (q4, q5, q6) after ``arm_q`` (q1, q2, q3) to ``out``."""
    w4, w5, w6 = k['w'][3:]
    s45, den, n45 = k['s45'], k['den'], k['n45']
    w4tv = _dot(w4, tv)
    alpha = (s45 * k['s56'] - w4tv) / den
    beta = (s45 * w4tv - k['s56']) / den
    gamma2 = (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * s45) / k['nn45']
    if not gamma2 > -1e-9:
        return
    root = math.sqrt(max(gamma2, 0.0))
    for gamma in (root, -root):
        z = tuple(alpha * w4[i] + beta * w5[i] + gamma * n45[i] for i in range(3))
        q5 = math.atan2(_dot(z, k['w5_up6']), _dot(z, k['up6']))
        q5a = alias(4, q5)
        if q5a is None:
            continue
        up = _normal(z, w4)
        if math.sqrt(_dot(up, up)) < 1e-9:             # wrist singularity
            q4 = q_ref[3]
        else:
            q4 = math.atan2(_dot(_cross(w4, up), tv), _dot(up, tv))
        q4a = alias(3, q4)
        if q4a is None:
            continue
        # q6: Rot6 x6 = Rot5^T Rot4^T R_w x6.
        target = _rotate(w5, math.sin(-q5), math.cos(-q5),
                         _rotate(w4, math.sin(-q4), math.cos(-q4), tx))
        q6 = math.atan2(_dot(target, k['w6_upx6']), _dot(target, k['upx6']))
        q6a = alias(5, q6)
        if q6a is None:
            continue
        out.append(list(arm_q) + [q4a, q5a, q6a])


def _reproduces(k, q, R, t, tol):
    """Return whether FK of ``q`` is within ``tol`` of the pose ``R``, ``t`` (the batch test)."""
    b = k['tip_R']                       # the product so far, row-major (9)
    p = k['tip']
    for i in range(5, -1, -1):
        s, o = math.sin(q[i]), 1.0 - math.cos(q[i])
        K, KK, r = k['K'][i], k['KK'][i], k['r'][i]
        a = [e + s * x + o * y for e, x, y in zip(IDENTITY_ROWS, K, KK)]   # Rot(w_i, q_i)
        d0, d1, d2 = p[0] - r[0], p[1] - r[1], p[2] - r[2]
        p = (a[0] * d0 + a[1] * d1 + a[2] * d2 + r[0], a[3] * d0 + a[4] * d1 + a[5] * d2 + r[1],
             a[6] * d0 + a[7] * d1 + a[8] * d2 + r[2])
        b = [a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
             a[0] * b[2] + a[1] * b[5] + a[2] * b[8], a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
             a[3] * b[1] + a[4] * b[4] + a[5] * b[7], a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
             a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
             a[6] * b[2] + a[7] * b[5] + a[8] * b[8]]
    dp = (p[0] - t[0]) ** 2 + (p[1] - t[1]) ** 2 + (p[2] - t[2]) ** 2
    chord = sum((x - y) ** 2 for x, y in zip(b, R[0] + R[1] + R[2]))
    return dp < tol * tol and chord < 8.0 * math.sin(tol / 2.0) ** 2
