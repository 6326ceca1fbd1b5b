"""
Closed-form inverse kinematics of 6R arms with a spherical wrist: every solution, vectorised.

The solver is derived from the model's own geometry (product of exponentials at ``q = 0``), not
written for one robot. It applies to any 6R ``ArmModel`` whose

- axes 4, 5 and 6 meet in one point (the wrist centre; its position depends on q1..q3 only),
- axes 2 and 3 are parallel (a planar 2R elbow after the base joint), axis 1 is not.

That covers the Mover6, the miniBOT report's miniBOT and most industrial arms. Steps (Paden-Kahan
subproblems on the space-frame screws ``omega_i``, ``r_i`` at ``q = 0``):

1. wrist centre ``p = T @ w_tool`` (``w_tool``: the wrist centre in the tip frame, constant);
2. q1: joints 2 and 3 keep the wrist centre's component along axis 2 fixed, so
   ``a cos q1 + b sin q1 = c`` (two branches, shoulder left / right);
3. q3: rotations about axis 2 keep the distance to that axis, so the law of cosines in the plane
   normal to it gives q3 (two branches, elbow up / down); q2 then turns the point into place;
4. q4, q5: ``Rot4 Rot5 omega_6 = R_w omega_6`` (subproblem 2, two branches, wrist flip), q6 from
   what is left (subproblem 1).

Up to 8 candidates per pose. Each angle is given as the value nearest ``q_ref`` (default 0) by
whole turns, moved by one more turn when that brings it inside the limits (joints with more
than a full turn of range have several valid values: the one continuous with ``q_ref`` is
returned). Every candidate is checked by forward kinematics, and those out of joint limits are
dropped when ``within_limits`` is set. At a wrist
singularity (axes 4 and 6 aligned) only q4 + q6 matters: q4 is taken from ``q_ref``; likewise q1
at a shoulder singularity (wrist centre on axis 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

from mover6_control.kinematics.ik_one_pose import ik_one_pose
from mover6_control.kinematics.rotations import validate_transform
from mover6_control.kinematics.wrist import (cross3, norm3, VERIFY_TOL, wrist_geometry,
                                             WristGeometry)
from mover6_control.validation import as_finite_array
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

N_BRANCHES = 8


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _q6_basis(geo: WristGeometry) -> np.ndarray:
    """
    Return ``B`` (3, 18): q6's two dot products as products of ``tx`` and sines and cosines.

    q6 = atan2(t . a, t . b) with ``t = Rot(w5, -q5) Rot(w4, -q4) tx``, ``b`` = x6 normal to
    w6 and ``a = w6 x b``. ``t . a = tx . Rot(w4, q4) Rot(w5, q5) a``, and a turn of a constant
    vector is ``Rot(w, q) v = v_par + cos(q) v_perp + sin(q) w x v``. So ``t . a`` is
    ``sum_ik f_i(q4) g_k(q5) (tx . B_ik)`` with f, g = (1, cos, sin); columns 3 i + k of ``B``
    (i = 0, 1, 2 for a; 3, 4, 5 for b).
    """
    w4, w5, w6 = geo.omega[3:]
    b = geo.x6 - np.dot(geo.x6, w6) * w6
    a = cross3(w6, b)

    def parts(w, v):
        par = np.dot(v, w) * w
        return par, v - par, cross3(w, v)

    columns = []
    for target in (a, b):
        inner = parts(w5, target)                                   # g_k(q5) terms
        outer = [parts(w4, v) for v in inner]                       # f_i(q4) of each
        columns += [outer[k][i] for i in range(3) for k in range(3)]
    B = np.array(columns).T
    B.setflags(write=False)
    return B


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _wrist_basis(geo: WristGeometry) -> np.ndarray:
    """Return (3, 22): w4, w5, n45 = w4 x w5, w4 x n45, then the columns of ``_q6_basis``."""
    w4, w5 = geo.omega[3], geo.omega[4]
    n45 = cross3(w4, w5)
    B = np.column_stack([w4, w5, n45, cross3(w4, n45), _q6_basis(geo)])
    B.setflags(write=False)
    return B


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _q5_constants(geo: WristGeometry) -> tuple:
    """Return z . (w5 x u6) and z . u6 per unit of alpha, beta, gamma (u6: w6 normal to w5)."""
    w4, w5, w6 = geo.omega[3:]
    up = w6 - np.dot(w6, w5) * w5
    n45 = cross3(w4, w5)
    return tuple(float(np.dot(v, c)) for c in (cross3(w5, up), up) for v in (w4, w5, n45))


def _wrap(q):
    """
    Wrap angles to [-pi, pi): ``(q + pi) % 2 pi - pi``, the remainder only where it changes q.

    ``x % 2 pi`` is ``x`` itself for ``x`` in [0, 2 pi), so only the angles outside pay for
    the (slow) remainder; the result is the same number for number.
    """
    x = q + np.pi
    if np.ndim(x) == 0:
        return x % (2.0 * np.pi) - np.pi
    out = x - np.pi
    if x.size and (x.min() < 0.0 or x.max() >= 2.0 * np.pi):
        outside = (x < 0.0) | (x >= 2.0 * np.pi)
        out[outside] = x[outside] % (2.0 * np.pi) - np.pi
    return out


def nearest_alias(arm: ArmModel, Q: np.ndarray, q_ref: np.ndarray,
                  within_limits: bool = True) -> np.ndarray:
    """
    Return ``Q`` (..., n) with each angle moved by whole turns to lie nearest ``q_ref``.

    Then, with ``within_limits``, an angle still outside its limits is moved by one more turn
    when that brings it inside (joints whose range exceeds a full turn have several valid
    values; the one continuous with ``q_ref`` is wanted).
    """
    Q = q_ref + _wrap(Q - q_ref)
    return _into_limits(arm, Q) if within_limits else Q


def _into_limits(arm, Q):
    """Shift each angle by +-2 pi when that brings it inside its joint limits."""
    return _into_range(Q, arm.lower, arm.upper)


def _into_range(Q, lo, hi):
    """Shift each angle by +-2 pi when that brings it inside [lo, hi] (broadcast)."""
    below, above = Q < lo, Q > hi
    if not (below.any() or above.any()):
        return Q
    up = Q + 2.0 * np.pi
    down = Q - 2.0 * np.pi
    Q = np.where(below & (up >= lo) & (up <= hi), up, Q)
    return np.where((Q > hi) & (down >= lo) & (down <= hi), down, Q)


def pose_errors_batch(T_goal: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return position [m] and orientation [rad] errors between poses (..., 4, 4).

    The orientation error is the angle of ``R_goal^T R``, from the chord
    ``|R - R_goal|_F = 2 sqrt(2) sin(angle / 2)``, accurate for small angles.
    """
    dp = np.linalg.norm(T[..., :3, 3] - T_goal[..., :3, 3], axis=-1)
    chord = np.linalg.norm(T[..., :3, :3] - T_goal[..., :3, :3], axis=(-2, -1))
    return dp, 2.0 * np.arcsin(np.clip(chord / (2.0 * np.sqrt(2.0)), 0.0, 1.0))


@dataclass(frozen=True, eq=False)
class _Plan:
    """The batch solver's constants of one ``WristGeometry``, prepared once (``_plan``)."""

    rows: np.ndarray       # (39, 12): per-pose rows, linear in the pose's top 12 entries
    offset: np.ndarray     # (39, 1): their constant parts
    q3: tuple              # phi3, rho3, safe rho3, (|e|^2 + |u|^2) / 2: q3's equation
    elbow: np.ndarray      # (2, 3): the plane coordinates of x - r2 are k0 + cos q3 k1 + sin q3 k2
    sigma: float           # w3 = sigma w2 exactly (+-1), or 0: turn about w3 in full
    w3: np.ndarray         # (3,): w3 in the basis (e1, e2, w2) of the elbow plane
    tv_basis: np.ndarray   # (4, 3): w4, w5, n45, w4 x n45 in that basis
    tx_basis: np.ndarray   # (18, 3): the columns of ``_q6_basis`` in that basis
    wrist: tuple           # alpha, beta, gamma^2 and q5 constants


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _plan(geo: WristGeometry) -> _Plan:
    """
    Return the constants of the batch solver for ``geo``.

    Everything the solver needs of a pose before any joint is known is linear in the pose's
    top 12 entries (with a constant part): 39 rows of one matrix product per block of poses,

    - 0-2: q1's equation ``a cos q1 + b sin q1 = c``;
    - 3-8: the wrist centre seen from axis 2 after turning back by q1, in the plane normal to
      w2 with the basis (e1, e2): ``d = D0 + cos q1 D1 + sin q1 D2`` for each of e1, e2;
    - 9-26: the goal's axes ``g`` (R_goal M^T w6 and R_goal M^T x6) turned back by q1, in the
      basis (e1, e2, w2): ``g . Rot(w1, q1) b = g . b_par + cos q1 g . b_perp
      + sin q1 g . (w1 x b)`` for b = e1, e2, w2;
    - 27-38: the pose's entries themselves (for the FK check, in the same layout).
    """
    w1, w2, w3, w4, w5, w6 = geo.omega
    r1, r2, r3 = geo.r[:3]
    p0 = geo.wrist_point
    e1 = cross3(w2, [1.0, 0.0, 0.0])
    if norm3(e1) < 0.5:
        e1 = cross3(w2, [0.0, 1.0, 0.0])
    e1 = e1 / norm3(e1)
    e2 = cross3(w2, e1)
    basis = np.array([e1, e2, w2])                     # rows: coordinates in the plane basis
    M_R = geo.M[:3, :3]
    wit = geo.wrist_in_tip
    s12 = np.dot(w1, w2)

    def of_p(k):
        """Row of ``p . k`` (p = R wit + t) over the pose's top 12 entries."""
        row = np.zeros((3, 4))
        row[:3, :3] = np.outer(k, wit)
        row[:3, 3] = k
        return row.reshape(12)

    def of_g(gc, k):
        """Row of ``(R gc) . k``."""
        row = np.zeros((3, 4))
        row[:3, :3] = np.outer(k, gc)
        return row.reshape(12)

    rows, offset = [], []
    ka, kb = w2 - s12 * w1, cross3(w1, w2)
    rows += [of_p(ka), of_p(kb), of_p(-s12 * w1)]
    offset += [-np.dot(r1, ka), -np.dot(r1, kb), np.dot(w2, p0 - r1) + s12 * np.dot(r1, w1)]
    for e in (e1, e2):
        par = np.dot(w1, e) * w1
        ew1 = cross3(e, w1)
        rows += [of_p(par), of_p(e - par), of_p(-ew1)]
        offset += [np.dot(r1 - r2, e) - np.dot(r1, par), -np.dot(r1, e - par), np.dot(r1, ew1)]
    for gc in (M_R.T @ w6, M_R.T @ geo.x6):
        for b in basis:
            par = np.dot(w1, b) * w1
            rows += [of_g(gc, par), of_g(gc, b - par), of_g(gc, cross3(w1, b))]
            offset += [0.0, 0.0, 0.0]
    e = (r3 - r2) - np.dot(r3 - r2, w2) * w2
    u = (p0 - r3) - np.dot(p0 - r3, w2) * w2
    a3, b3 = np.dot(e, u), np.dot(e, cross3(w3, u))
    rho3 = np.hypot(a3, b3)
    v = p0 - r3
    v_par = np.dot(v, w3) * w3
    elbow = basis[:2] @ np.column_stack([(r3 - r2) + v_par, v - v_par, cross3(w3, v)])
    sigma = float(np.dot(w2, w3))
    sigma = sigma if np.array_equal(w3, sigma * w2) and abs(sigma) == 1.0 else 0.0
    w4, w5 = geo.omega[3], geo.omega[4]
    s45, s56 = np.dot(w4, w5), np.dot(w5, w6)
    den = s45 ** 2 - 1.0
    n45 = cross3(w4, w5)
    wb = _wrist_basis(geo)
    rows += list(np.eye(12))                           # 27-38: the pose's entries, for the check
    offset += [0.0] * 12
    plan = _Plan(rows=np.array(rows), offset=np.array(offset)[:, None],
                 q3=(float(np.arctan2(b3, a3)), float(rho3), float(rho3 if rho3 > 1e-12 else 1.0),
                     float((np.dot(e, e) + np.dot(u, u)) / 2.0)),
                 elbow=elbow, sigma=sigma, w3=basis @ w3,
                 tv_basis=np.ascontiguousarray((basis @ wb[:, :4]).T),
                 tx_basis=np.ascontiguousarray((basis @ wb[:, 4:]).T),
                 wrist=(s45, s56, den, float(np.dot(n45, n45))) + _q5_constants(geo))
    for a in (plan.rows, plan.offset, plan.elbow, plan.w3, plan.tv_basis, plan.tx_basis):
        a.setflags(write=False)
    return plan


_WRIST_BLOCK = 4096      # branches reaching the wrist per block of ik_closed_form_batch


def _alias(q, ref, lo, hi, within_limits):
    """
    Return ``q`` aliased nearest ``ref`` (and into [lo, hi]) and where it is inside the limits.

    The steps of ``nearest_alias`` for one joint: the same numbers. Without ``within_limits``
    the mask is None (every value kept).
    """
    q = ref + _wrap(q - ref)
    if not within_limits:
        return q, None
    # A turn up can bring a value inside only if the smallest one turned up is <= hi, a turn
    # down only if the largest one turned down is >= lo (rounding is monotone): else none moves.
    if q.size and (q.min() + 2.0 * np.pi <= hi or q.max() - 2.0 * np.pi >= lo):
        q = _into_range(q, lo, hi)
    return q, (q >= lo - 1e-9) & (q <= hi + 1e-9)


def _keep(ok, inside):
    """
    Return where the (2, n) entries are ``ok`` (n,) and (given) ``inside``: entry and root.

    The flat index ``root * n + entry`` is split into the entry (n) and the root (0 or 1).
    """
    n = len(ok)
    flat = np.flatnonzero(np.broadcast_to(ok, (2, n)) if inside is None else ok & inside)
    root = flat >= n
    return flat, flat - n * root, root


def _pair(a, b, op):
    """Return the (2, n) array of ``a + b`` and ``op(a, b)`` (the two roots or flips)."""
    out = np.empty((2,) + np.shape(a if np.ndim(a) else b))
    np.add(a, b, out=out[0])
    op(a, b, out=out[1])
    return out


def _cos_sin_of_atan2(y, x):
    """Return the cosine and sine of ``atan2(y, x)``: ``x / hypot``, ``y / hypot`` (1, 0 at 0)."""
    h = np.sqrt(x * x + y * y)
    zero = h == 0.0
    if zero.any():
        h[zero] = 1.0
        x = np.where(zero, 1.0, x)
    inv = 1.0 / h
    return x * inv, y * inv


def _solve(arm, geo, T, q_ref, within_limits, tol, Q, ok):
    """
    Fill ``Q`` (m, 8, 6) and ``ok`` (m, 8) for poses ``T`` (m, 4, 4).

    Returns the used-ref mask (m,) and the number of branches that reached the wrist.

    The steps of the module docstring, on flat arrays of the branches still in question: a
    branch whose joint is unsolvable or (with ``within_limits``) outside its limits is dropped
    as soon as that joint is known, before the joints after it are solved. ``pos`` follows each
    branch's place in ``Q`` (pose * 8 + shoulder * 4 + elbow * 2 + wrist flip); ``carry`` its
    joints so far. Branches that are dropped keep ``q_ref``'s values in ``Q``.
    """
    m = len(T)
    plan = _plan(geo)
    lo, hi = arm.lower, arm.upper
    Q[...] = q_ref[:, None, :]
    ok[...] = False
    ref = np.ascontiguousarray(q_ref.T)                        # (6, m): each joint's row
    used_ref = np.zeros(m, dtype=bool)
    X = plan.rows @ T.reshape(m, 16)[:, :12].T
    X += plan.offset
    # q1 (two roots per pose): a cos q1 + b sin q1 = c.
    a, b, c = X[0], X[1], X[2]
    rho = np.sqrt(a * a + b * b)
    ok1 = np.abs(c) <= rho + 1e-12
    delta = np.arccos(np.clip(c / np.where(rho > 1e-12, rho, 1.0), -1.0, 1.0))
    q1 = _pair(np.arctan2(b, a), delta, np.subtract)                         # (2, m)
    shoulder = rho < 1e-9
    if shoulder.any():
        q1[:, shoulder] = ref[0, shoulder]
        ok1 |= shoulder & (np.abs(c) < 1e-9)
        used_ref |= shoulder
    q1a, inside = _alias(q1, ref[0], lo[0], hi[0], within_limits)
    sel, pose, root = _keep(ok1, inside)
    pos = pose * 8 + 4 * root
    carry = q1a.reshape(-1).take(sel)[None]
    q1 = q1.reshape(-1).take(sel)
    s1, c1 = np.sin(q1), np.cos(q1)
    # q3 (two roots per branch): the wrist centre's distance to axis 2, law of cosines.
    D = X[3:9].take(pose, axis=1)
    dx = D[0] + c1 * D[1] + s1 * D[2]
    dy = D[3] + c1 * D[4] + s1 * D[5]
    phi3, rho3, safe3, half = plan.q3
    rhs = 0.5 * (dx * dx + dy * dy) - half
    ok3 = np.abs(rhs) <= rho3 + 1e-12
    q3 = _pair(phi3, np.arccos(np.clip(rhs / safe3, -1.0, 1.0)), np.subtract)  # (2, n)
    q3a, inside = _alias(q3, ref[2].take(pose), lo[2], hi[2], within_limits)
    sel, j, root = _keep(ok3, inside)
    pos = pos[j] + 2 * root
    pose = pos >> 3
    carry = np.concatenate([carry.take(j, axis=1), q3a.reshape(1, -1).take(sel, axis=1)])
    s1, c1, dx, dy = s1[j], c1[j], dx[j], dy[j]
    q3 = q3.reshape(-1).take(sel)
    s3, c3 = np.sin(q3), np.cos(q3)
    # q2 turns x - r2 (x: the wrist centre turned by q3) onto d, both in the elbow plane.
    k = plan.elbow
    ux = k[0, 0] + c3 * k[0, 1] + s3 * k[0, 2]
    uy = k[1, 0] + c3 * k[1, 1] + s3 * k[1, 2]
    y2 = ux * dy - uy * dx
    x2 = ux * dx + uy * dy
    q2a, inside = _alias(np.arctan2(y2, x2), ref[1].take(pose), lo[1], hi[1], within_limits)
    # Rows of the branches that reach the wrist: q1, q2, q3, then s1, c1, s2, c2, s3, c3.
    A = np.concatenate([carry[:1], q2a[None], carry[1:], s1[None], c1[None], x2[None],
                        y2[None], s3[None], c3[None]])
    if inside is not None:
        A = A.take(np.flatnonzero(inside), axis=1)
        pos = pos[inside]
        pose = pos >> 3
    n_wrist = n = len(pos)
    s1, c1, s3, c3 = A[3], A[4], A[7], A[8]
    # The goal's two axes turned back by q1, q2, q3, in the basis (e1, e2, w2) of the plane.
    A[6], A[5] = _cos_sin_of_atan2(A[6], A[5])
    s2, c2 = A[5], A[6]
    G = X[9:27].take(pose, axis=1).reshape(6, 3, n)
    G = G[:, 0] + c1 * G[:, 1] + s1 * G[:, 2]                                  # (6, n)
    if plan.sigma:
        cq, sq = c2 * c3 - plan.sigma * s2 * s3, s2 * c3 + plan.sigma * c2 * s3
    else:
        cq, sq = c2, s2
    turned = np.empty((2, 3, n))
    for i in range(2):
        x, y = G[3 * i], G[3 * i + 1]
        turned[i, 0] = x * cq + y * sq
        turned[i, 1] = y * cq - x * sq
        turned[i, 2] = G[3 * i + 2]
    if not plan.sigma:
        turned = _turn_back(plan.w3, s3, c3, turned)
    tv = plan.tv_basis @ turned[0]                                             # (4, n)
    tx = plan.tx_basis @ turned[1]                                             # (18, n)
    # The wrist: z = alpha w4 + beta w5 +- gamma n45 (subproblem 2), q5 then q4.
    s45, s56, den, nn45 = plan.wrist[:4]
    k5 = plan.wrist[4:]
    a4, a5, an, am = tv
    alpha = (s45 * s56 - a4) / den
    beta = (s45 * a4 - s56) / den
    gamma2 = (1.0 - alpha ** 2 - beta ** 2 - 2.0 * alpha * beta * s45) / nn45
    ok_w = gamma2 > -1e-9
    gamma = np.sqrt(np.maximum(gamma2, 0.0))
    lever = np.sqrt((beta ** 2 + gamma ** 2) * nn45)
    singular = lever < 1e-9
    gamma = np.stack([gamma, -gamma])                                         # (2, n): flips
    y5 = (alpha * k5[0] + beta * k5[1]) + gamma * k5[2]
    x5 = (alpha * k5[3] + beta * k5[4]) + gamma * k5[5]
    q5a, inside5 = _alias(np.arctan2(y5, x5), ref[4].take(pose), lo[4], hi[4], within_limits)
    y4 = beta * an + gamma * am
    x4 = beta * (a5 - s45 * a4) + gamma * an
    q4 = np.arctan2(y4, x4)
    ref4 = ref[3].take(pose)
    if singular.any():
        used_ref[pose[singular]] = True
        q4 = np.where(singular, ref4, q4)
        y4 = np.where(singular, np.sin(ref4), y4)
        x4 = np.where(singular, np.cos(ref4), x4)
    q4a, inside4 = _alias(q4, ref4, lo[3], hi[3], within_limits)
    sel, j, root = _keep(ok_w, None if inside5 is None else inside5 & inside4)
    pos = pos[j] + root
    pose = pos >> 3
    c5, s5 = _cos_sin_of_atan2(y5.reshape(-1)[sel], x5.reshape(-1)[sel])
    c4, s4 = _cos_sin_of_atan2(y4.reshape(-1)[sel], x4.reshape(-1)[sel])
    # q6 from two dot products of the turned R_w x6 (see _q6_basis).
    d = tx.take(j, axis=1)
    h = [d[3 * i] + c5 * d[3 * i + 1] + s5 * d[3 * i + 2] for i in range(6)]
    y6, x6 = h[0] + c4 * h[1] + s4 * h[2], h[3] + c4 * h[4] + s4 * h[5]
    q6a, inside = _alias(np.arctan2(y6, x6), ref[5].take(pose), lo[5], hi[5], within_limits)
    # The same rows for the wrist: q4, q5, q6, s4, c4, s5, c5, s6, c6.
    B = np.empty((9, len(sel)))
    np.take(q4a, sel, out=B[0])
    np.take(q5a, sel, out=B[1])
    B[2], B[3], B[4], B[5], B[6] = q6a, s4, c4, s5, c5
    B[8], B[7] = _cos_sin_of_atan2(y6, x6)
    if inside is not None:
        keep = np.flatnonzero(inside)
        j, B, pos = j[keep], B.take(keep, axis=1), pos[keep]
        pose = pos >> 3
    A = A.take(j, axis=1)
    Q.reshape(-1, 6)[pos] = np.concatenate([A[:3], B[:3]]).T
    sin_cos = [(A[3], A[4]), (A[5], A[6]), (A[7], A[8]), (B[3], B[4]), (B[5], B[6]),
               (B[7], B[8])]
    # FK check of the candidates left, on squared figures (no roots): |dp|^2 < tol^2 and the
    # rotation chord |R - R_goal|_F^2 = 8 sin^2(angle / 2) < 8 sin^2(tol / 2). The chain is
    # multiplied out from the sines and cosines found above (of the same angles up to whole
    # turns).
    if len(pos):
        F = np.empty((12, len(pos)))
        F[...] = _fk_rows(arm, sin_cos)
        F -= X[27:].take(pose, axis=1)
        F *= F
        position = F[3] + F[7] + F[11]
        chord = F[0] + F[1] + F[2] + F[4] + F[5] + F[6] + F[8] + F[9] + F[10]
        ok.reshape(-1)[pos] = (position < tol ** 2) & (chord < 8.0 * np.sin(tol / 2.0) ** 2)
    return used_ref, n_wrist


def _times(a, b):
    """Return ``a * b`` for floats or arrays, skipping exact zeros and ones of floats."""
    if isinstance(a, float):
        if a == 0.0 or (isinstance(b, float) and b == 0.0):
            return 0.0
        return b if a == 1.0 else a * b
    if isinstance(b, float):
        return a if b == 1.0 else (0.0 if b == 0.0 else a * b)
    return a * b


def _plus(a, b):
    """Return ``a + b`` for floats or arrays, skipping exact float zeros."""
    if isinstance(a, float) and a == 0.0:
        return b
    if isinstance(b, float) and b == 0.0:
        return a
    return a + b


def _frame_times(R, p, A, t):
    """Return the frame ``(R, p) (A, t)`` (3 x 3 and 3 entries, floats or arrays)."""
    R2 = [[0.0] * 3 for _ in range(3)]
    p2 = list(p)
    for k in range(3):
        for j in range(3):
            for m in range(3):
                R2[k][j] = _plus(R2[k][j], _times(R[k][m], A[m][j]))
            p2[k] = _plus(p2[k], _times(R[k][j], t[j]))
    return R2, p2


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _chain_steps(arm: ArmModel) -> tuple:
    """Return per joint its origin (rotation rows, translation) and axis as Python floats."""
    def split(T):
        return T[:3, :3].tolist(), T[:3, 3].tolist()
    return (tuple((split(origin), tuple(axis.tolist()))
                  for origin, axis in zip(arm.origins, arm.axes)), split(arm.tool))


def _rotation(axis, s, c):
    """Return ``Rot(axis, q)`` (3 x 3, floats or arrays) of sine ``s`` and cosine ``c``."""
    j = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[j]) - 1.0) < 1e-15 and sum(abs(x) for x in axis) == abs(axis[j]):
        a, b = (j + 1) % 3, (j + 2) % 3
        s = s if axis[j] > 0.0 else -s
        rot = [[0.0] * 3 for _ in range(3)]
        rot[j][j] = 1.0
        rot[a][a], rot[b][b], rot[b][a], rot[a][b] = c, c, s, -s
        return rot
    K = [[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]]
    KK = (np.array(K) @ np.array(K)).tolist()
    v = 1.0 - c
    return [[_plus(_plus(float(k == j), _times(K[k][j], s)), _times(KK[k][j], v))
             for j in range(3)] for k in range(3)]


def _fk_entries(arm, sin_cos):
    """
    Return the tip pose's top rows (12 entries, row-major) of the joints given by sin and cos.

    ``sin_cos``: per joint its sine and cosine. The chain of ``forward`` (origin, then the turn
    about the joint's axis) entry by entry; entries that are exact constants (the zeros and ones
    of the origins) cost nothing.
    """
    steps, (tool_R, tool_t) = _chain_steps(arm)
    R = [[float(k == j) for j in range(3)] for k in range(3)]
    p = [0.0, 0.0, 0.0]
    for ((O_R, O_t), axis), (s, c) in zip(steps, sin_cos):
        R, p = _frame_times(R, p, O_R, O_t)
        R, _ = _frame_times(R, [0.0] * 3, _rotation(axis, s, c), [0.0] * 3)
    R, p = _frame_times(R, p, tool_R, tool_t)
    return [R[0][0], R[0][1], R[0][2], p[0], R[1][0], R[1][1], R[1][2], p[1],
            R[2][0], R[2][1], R[2][2], p[2]]


class _Slot:
    """A value of the FK chain while ``_fk_program`` records it: its operations go on a list."""

    __slots__ = ('ops', 'index')

    def __init__(self, ops, index):
        self.ops, self.index = ops, index

    def _record(self, ufunc, *args):
        out = _Slot(self.ops, self.ops.count)
        self.ops.count += 1
        self.ops.append((ufunc, out.index,
                         tuple(a.index if isinstance(a, _Slot) else float(a) for a in args)))
        return out

    def __mul__(self, other):
        return self._record(np.multiply, self, other)

    def __rmul__(self, other):
        return self._record(np.multiply, other, self)

    def __add__(self, other):
        return self._record(np.add, self, other)

    def __radd__(self, other):
        return self._record(np.add, other, self)

    def __rsub__(self, other):
        return self._record(np.subtract, other, self)

    def __neg__(self):
        return self._record(np.negative, self)


class _Ops(list):
    """The recorded operations, and the number of values (slots) they use."""

    count = 0


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _fk_program(arm: ArmModel) -> tuple:
    """
    Return the array operations of ``_fk_entries`` for ``arm``, recorded once.

    Slots 2 i and 2 i + 1 hold joint i's sine and cosine; then ``(ufunc, out, args, free)`` in
    order (an int arg is a slot, a float a constant; ``free``: the slots used for the last
    time), the number of slots and the 12 entries (slot or constant).
    """
    ops = _Ops()
    ops.count = 12
    entries = _fk_entries(arm, [(_Slot(ops, 2 * i), _Slot(ops, 2 * i + 1)) for i in range(6)])
    entries = tuple(e.index if isinstance(e, _Slot) else float(e) for e in entries)
    # After each operation, the slots no longer needed are let go (the working set stays in
    # cache): a slot's last use, unless it is an entry.
    last = {}
    for k, (_, _, args) in enumerate(ops):
        for a in args:
            if type(a) is int:
                last[a] = k
    done = [[] for _ in ops]
    for slot, k in last.items():
        if slot not in entries:
            done[k].append(slot)
    return (tuple((ufunc, out, args, tuple(free))
                  for (ufunc, out, args), free in zip(ops, done)), ops.count, entries)


def _fk_rows(arm, sin_cos):
    """Return ``_fk_entries`` for arrays of sines and cosines (its recorded operations)."""
    ops, count, entries = _fk_program(arm)
    v = [None] * count
    for i, (s, c) in enumerate(sin_cos):
        v[2 * i], v[2 * i + 1] = s, c
    for ufunc, out, args, free in ops:
        v[out] = ufunc(*[v[a] if type(a) is int else a for a in args])
        for a in free:
            v[a] = None
    return [v[e] if type(e) is int else e for e in entries]


def _turn_back(w, s, c, v):
    """Turn ``v`` (2, 3, n) by minus the angle of sine, cosine ``s``, ``c`` about ``w`` (3,)."""
    out = np.empty_like(v)
    d = (w[0] * v[:, 0] + w[1] * v[:, 1] + w[2] * v[:, 2]) * (1.0 - c)
    for i in range(3):
        a, b = (i + 1) % 3, (i + 2) % 3
        cross = w[a] * v[:, b] - w[b] * v[:, a]                   # (w x v)_i
        out[:, i] = v[:, i] * c - cross * s + w[i] * d
    return out


def _as_q_ref(arm, q_ref, m):
    """Return the reference configurations (m, n) used at singular poses."""
    if q_ref is None:
        return np.zeros((m, arm.n_joints))
    q_ref = np.asarray(q_ref, dtype=float)
    if q_ref.ndim == 1:
        q_ref = np.broadcast_to(arm.check_q(q_ref, 'q_ref'), (m, arm.n_joints))
    return as_finite_array(q_ref, (m, arm.n_joints), 'q_ref')


def ik_closed_form_batch(arm: ArmModel, T: np.ndarray, within_limits: bool = True,
                         q_ref: np.ndarray | None = None, tol: float = VERIFY_TOL,
                         chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """
    Solve many poses at once: ``T`` (m, 4, 4) -> ``(Q (m, 8, 6), valid (m, 8))``.

    ``Q[k, b]`` is branch ``b`` of pose ``k`` [rad]; ``valid`` marks the branches that reproduce
    the pose by FK within ``tol`` ([m] and [rad]) and, with ``within_limits``, respect the joint
    limits. A branch that is not valid is no solution (one dropped before the FK check holds
    ``q_ref``'s values, see ``solve_candidates``). Poses are checked for shape and finiteness
    only (no orthonormality test: use ``ik_closed_form`` for one untrusted pose). ``q_ref``
    (6,) or (m, 6) picks q1 and q4 at shoulder and wrist singularities. Raises
    ``InvalidInputError`` for arms the closed form does not cover. At most ``chunk`` poses are
    solved at a time, fewer when many branches reach the wrist (cache-sized blocks).
    """
    geo = wrist_geometry(arm)
    T = as_finite_array(T, (None, 4, 4), 'poses')
    m = len(T)
    q_ref = _as_q_ref(arm, q_ref, m)
    Q = np.empty((m, N_BRANCHES, 6))
    ok = np.empty((m, N_BRANCHES), dtype=bool)
    # Blocks of poses whose arrays stay in cache: at most ``chunk`` poses and about
    # _WRIST_BLOCK branches reaching the wrist (the first, small block measures how many do).
    lo, size = 0, min(chunk, 512)
    while lo < m:
        sl = slice(lo, lo + size)
        _, n_wrist = _solve(arm, geo, T[sl], q_ref[sl], within_limits, tol, Q[sl], ok[sl])
        per_pose = n_wrist / len(Q[sl])
        lo += size
        size = int(min(chunk, max(64, _WRIST_BLOCK / max(per_pose, 1e-3))))
    return Q, ok


def solve_candidates(arm: ArmModel, geo: WristGeometry, T: np.ndarray, q_ref: np.ndarray,
                     within_limits: bool = True, tol: float = VERIFY_TOL,
                     return_ref_used: bool = False) -> tuple[np.ndarray, ...]:
    """
    Return the 8 candidates (m, 8, 6) of poses ``T`` (m, 4, 4) and the mask of verified ones.

    The unchecked core of ``ik_closed_form_batch`` for callers that solve pose after pose:
    ``geo`` from ``wrist_geometry(arm)``, ``q_ref`` (m, 6) already validated. A branch dropped
    before the FK check (one of its joints has no solution or, with ``within_limits``, is
    outside the limits) holds ``q_ref``'s values; one the FK check refuses holds its joints.
    With ``return_ref_used`` a third array (m,) marks the
    singular poses whose q1 or q4 came from ``q_ref`` (q4: on a branch whose q1..q3 are kept).
    """
    m = len(T)
    Q = np.empty((m, N_BRANCHES, 6))
    ok = np.empty((m, N_BRANCHES), dtype=bool)
    used_ref, _ = _solve(arm, geo, np.asarray(T, dtype=float), np.asarray(q_ref, dtype=float),
                         within_limits, tol, Q, ok)
    return (Q, ok, used_ref) if return_ref_used else (Q, ok)


def ik_closed_form(arm: ArmModel, T: np.ndarray, within_limits: bool = True,
                   q_ref: np.ndarray | None = None, tol: float = VERIFY_TOL) -> np.ndarray:
    """
    Return every solution (k, 6) [rad] for the pose ``T`` (4, 4); k = 0 when there is none.

    Each row reproduces ``T`` by FK within ``tol``; duplicates (the branches that meet at a
    singularity) appear once. With ``within_limits`` only solutions inside the joint limits are
    kept. The same steps as ``ik_closed_form_batch``, on Python floats for the one pose
    (``ik_one_pose``). Rows are sorted by distance to ``q_ref`` (default: zeros), nearest first.
    Raises ``InvalidInputError`` for a bad pose or an arm without a spherical wrist.
    """
    T = validate_transform(T, 'pose')
    ref = np.zeros(arm.n_joints) if q_ref is None else arm.check_q(q_ref, 'q_ref')
    sols = np.array(ik_one_pose(arm, T.tolist(), ref.tolist(), within_limits, tol))
    if len(sols) <= 1:
        return sols.reshape(-1, arm.n_joints)
    # Drop repeats (branches that meet at a singularity): keep the first of each group.
    gap = np.abs(_wrap(sols[:, None] - sols[None])).max(axis=-1)
    repeat = np.tril(gap <= 1e-9, k=-1).any(axis=1)
    out = sols[~repeat]
    return out[np.argsort(np.linalg.norm(out - ref, axis=1), kind='stable')]
