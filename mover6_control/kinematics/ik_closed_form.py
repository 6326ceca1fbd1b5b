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

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.forward import fk_batch
from mover6_control.kinematics.rotations import validate_transform
from mover6_control.validation import as_finite_array
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

N_BRANCHES = 8
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


def _cross(a, b):
    """Return the cross product of (..., 3) arrays (np.cross is slow on small inputs)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    out = np.empty(np.broadcast(a, b).shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _norm(v):
    """Return the Euclidean norm of a 3-vector as a float."""
    return float(np.sqrt(v @ v))


def _dot(a, b):
    """Return the dot product over the last axis."""
    return np.einsum('...i,...i->...', a, b)


def _skew(w):
    """Return the matrix ``K`` with ``K v = w x v``."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _times(v, A):
    """Return ``A @ v`` for vectors ``v`` (..., 3) and a constant (3, 3) ``A``, as one product."""
    return (v.reshape(-1, 3) @ A.T).reshape(v.shape)


def _rotate(w, theta, v):
    """Rotate vectors ``v`` (..., 3) about unit ``w`` (3,) by ``theta`` (...) [rad]."""
    return _rotate_sc(w, np.sin(theta), np.cos(theta), v)


def _rotate_sc(w, s, c, v):
    """Rotate ``v`` (..., 3) about unit ``w`` (3,) by the angle of sine and cosine ``s``, ``c``."""
    K = _skew(w)
    return v + s[..., None] * _times(v, K) + (1.0 - c)[..., None] * _times(v, K @ K)


def _subproblem1(w, u, v):
    """Return the angle about ``w`` that turns ``u`` onto ``v`` and ``|u|`` normal to ``w``."""
    P = np.eye(3) - np.outer(w, w)
    up = _times(u, P)
    wu = _times(up, _skew(w))
    return (np.arctan2(_dot(wu, v), _dot(up, v)), np.sqrt(_dot(up, up)))


def _angle_from(w, u, v):
    """Return the angle about ``w`` that turns the constant ``u`` (3,) onto ``v`` (..., 3)."""
    up = u - np.dot(u, w) * w
    # atan2(w . (up x v), up . v) = atan2(v . (w x up), v . up): one product for both.
    both = v.reshape(-1, 3) @ np.stack([_cross(w, up), up], axis=1)
    return np.arctan2(both[:, 0], both[:, 1]).reshape(v.shape[:-1])


def _atan2_cos_sin(y, x):
    """Return ``atan2(y, x)`` and its cosine and sine, ``x / hypot``, ``y / hypot`` (1, 0 at 0)."""
    h = np.hypot(x, y)
    zero = h == 0.0
    inv = 1.0 / np.where(zero, 1.0, h)
    return np.arctan2(y, x), np.where(zero, 1.0, x * inv), y * inv


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
    a = _cross(w6, b)

    def parts(w, v):
        par = np.dot(v, w) * w
        return par, v - par, _cross(w, v)

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
    n45 = _cross(w4, w5)
    B = np.column_stack([w4, w5, n45, _cross(w4, n45), _q6_basis(geo)])
    B.setflags(write=False)
    return B


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _q5_constants(geo: WristGeometry) -> tuple:
    """Return z . (w5 x u6) and z . u6 per unit of alpha, beta, gamma (u6: w6 normal to w5)."""
    w4, w5, w6 = geo.omega[3:]
    up = w6 - np.dot(w6, w5) * w5
    n45 = _cross(w4, w5)
    return tuple(float(np.dot(v, c)) for c in (_cross(w5, up), up) for v in (w4, w5, n45))


def _dots(v, B):
    """Return ``v . B[:, j]`` for vectors ``v`` (..., 3) and constants ``B`` (3, k): k rows."""
    return (B.T @ v.reshape(-1, 3).T).reshape((B.shape[1],) + v.shape[:-1])


def _cos_sin(a, b, c, tol):
    """Solve ``a cos t + b sin t = c``: both roots (..., 2), solvable mask, ``hypot(a, b)``."""
    rho = np.hypot(a, b)
    safe = np.where(rho > tol, rho, 1.0)
    ok = np.abs(c) <= rho + tol
    delta = np.arccos(np.clip(c / safe, -1.0, 1.0))
    phi = np.arctan2(b, a)
    return np.stack([phi + delta, phi - delta], axis=-1), ok, rho


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
    if _norm(_cross(omega[3], omega[4])) < 1e-6 or _norm(
            _cross(omega[4], omega[5])) < 1e-6:
        raise InvalidInputError(f'{arm.name}: neighbouring wrist axes are parallel; '
                                'no spherical wrist (use ik_numeric)')
    centre = np.linalg.solve(A, rhs)
    for i in (3, 4, 5):
        off = (centre - r[i]) - np.dot(centre - r[i], omega[i]) * omega[i]
        if _norm(off) > _POINT_TOL:
            raise InvalidInputError(
                f'{arm.name}: axes 4, 5, 6 do not meet in one point (axis {i + 1} misses it by '
                f'{_norm(off):.3g} m); no spherical wrist (use ik_numeric)')
    if _norm(_cross(omega[1], omega[2])) > _PARALLEL_TOL:
        raise InvalidInputError(
            f'{arm.name}: axes 2 and 3 are not parallel; this closed form needs a planar elbow '
            '(use ik_numeric)')
    if _norm(_cross(omega[0], omega[1])) < 1e-6:
        raise InvalidInputError(f'{arm.name}: axis 1 is parallel to axis 2 (use ik_numeric)')
    w2 = omega[1]
    e = (r[2] - r[1]) - np.dot(r[2] - r[1], w2) * w2
    u = (centre - r[2]) - np.dot(centre - r[2], w2) * w2
    if _norm(e) < _POINT_TOL or _norm(u) < _POINT_TOL:
        raise InvalidInputError(f'{arm.name}: degenerate elbow (zero link length)')
    M = frames[6]
    x6 = _cross(omega[5], [1.0, 0.0, 0.0])
    if _norm(x6) < 0.5:
        x6 = _cross(omega[5], [0.0, 1.0, 0.0])
    geometry = WristGeometry(omega=omega, r=r, M=M, wrist_point=centre,
                             wrist_in_tip=M[:3, :3].T @ (centre - M[:3, 3]),
                             x6=x6 / _norm(x6))
    return geometry


def has_spherical_wrist(arm: ArmModel) -> bool:
    """Return True when ``ik_closed_form`` can solve ``arm``."""
    try:
        wrist_geometry(arm)
    except InvalidInputError:
        return False
    return True


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
    outside = (x < 0.0) | (x >= 2.0 * np.pi)
    if outside.any():
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


def _candidates(geo, T, q_ref):
    """
    Return the joints of all 8 candidates, a mask of solvable ones and where q_ref was used.

    The joints as solved, each once per branch it depends on: q1 (m, 2), q2 and q3 (m, 2, 2),
    q4, q5, q6 (m, 2, 2, 2) (shoulder, elbow, wrist flip); the mask (m, 2, 2, 2).

    The last (m,) marks poses at a shoulder or wrist singularity, whose q1 or q4 came from
    ``q_ref``.
    """
    m = len(T)
    om, r = geo.omega, geo.r
    w1, w2, w3, w4, w5, w6 = om
    R_goal = T[:, :3, :3]
    p = np.einsum('mij,j->mi', R_goal, geo.wrist_in_tip) + T[:, :3, 3]      # (m, 3)
    p0 = geo.wrist_point
    # q1: w2 . (Rot(w1, -q1)(p - r1) + r1) = w2 . p0
    v = p - r[0]
    v1 = _dot(v, w1)
    s12 = np.dot(w1, w2)
    a = _dot(v, w2) - v1 * s12
    b = -_dot(_cross(w1, v), w2)
    c = np.dot(w2, p0 - r[0]) - v1 * s12
    q1, ok1, rho1 = _cos_sin(a, b, c, 1e-12)
    shoulder = rho1 < 1e-9
    q1 = np.where(shoulder[:, None], q_ref[:, None, 0], q1)
    ok1 = ok1 | (shoulder & (np.abs(c) < 1e-9))
    # sin and cos of q1 and q3 once each: both turn the wrist centre and the goal's axes.
    s1, c1 = np.sin(q1), np.cos(q1)
    p1 = r[0] + _rotate_sc(w1, -s1, c1, (p - r[0])[:, None, :])             # (m, 2, 3)
    # q3: distance of the wrist centre to axis 2, law of cosines about axis 3.
    e = (r[2] - r[1]) - np.dot(r[2] - r[1], w2) * w2
    u = (p0 - r[2]) - np.dot(p0 - r[2], w2) * w2
    d_vec = (p1 - r[1]) - _dot(p1 - r[1], w2)[..., None] * w2
    c3 = (_dot(d_vec, d_vec) - np.dot(e, e) - np.dot(u, u)) / 2.0
    q3, ok3, _ = _cos_sin(np.dot(e, u), np.dot(e, _cross(w3, u)), c3, 1e-12)  # (m, 2, 2)
    s3, c3 = np.sin(q3), np.cos(q3)
    x = r[2] + _rotate_sc(w3, s3, c3, np.broadcast_to(p0 - r[2], q3.shape + (3,)))
    q2, _ = _subproblem1(w2, x - r[1], p1[:, :, None, :] - r[1])             # (m, 2, 2)
    q1_pair = q1
    q1 = np.broadcast_to(q1[:, :, None], q2.shape)
    # The wrist must turn R_w = R03^T R_goal M^T; only R_w w6 and R_w x6 are needed, and
    # R03^T v = Rot(w3, -q3) Rot(w2, -q2) Rot(w1, -q1) v.
    M_R = geo.M[:3, :3]
    goal = R_goal.reshape(-1, 3) @ np.stack([M_R.T @ w6, M_R.T @ geo.x6], axis=1)
    goal = goal.reshape(m, 1, 3, 2).transpose(0, 1, 3, 2)                    # (m, 1, 2, 3)
    goal = _rotate_sc(w1, -s1[:, :, None], c1[:, :, None], np.broadcast_to(goal, (m, 2, 2, 3)))
    goal = _rotate(w2, -q2[..., None], np.broadcast_to(goal[:, :, None], q2.shape + (2, 3)))
    goal = _rotate_sc(w3, -s3[..., None], c3[..., None], goal)                # (m, 2, 2, 2, 3)
    # Every product the wrist needs of R_w w6 (tv) and R_w x6 (tx) with constant vectors, in
    # one product: tv . (w4, w5, n45, w4 x n45) and tx . the columns of _q6_basis.
    B = _wrist_basis(geo)
    a4, a5, an, am = _dots(goal[..., 0, :], B[:, :4])                         # (m, 2, 2) each
    # q4, q5: Rot4 Rot5 w6 = R_w w6 (subproblem 2 with axes through the wrist centre):
    # z = alpha w4 + beta w5 + gamma n45, with gamma = +-sqrt(gamma2) (the wrist flip).
    s45 = np.dot(w4, w5)
    den = s45 ** 2 - 1.0
    s56 = np.dot(w5, w6)
    alpha = (s45 * s56 - a4) / den
    beta = (s45 * a4 - s56) / den
    n45 = _cross(w4, w5)
    nn45 = np.dot(n45, n45)
    gamma2 = (1.0 - alpha ** 2 - beta ** 2 - 2.0 * alpha * beta * s45) / nn45
    ok_w = gamma2 > -1e-9
    gamma = np.sqrt(np.maximum(gamma2, 0.0))
    gamma = np.stack([gamma, -gamma], axis=-1)                                # (m, 2, 2, 2)
    alpha, beta = alpha[..., None], beta[..., None]
    # q5 turns w6 onto z: atan2(z . (w5 x u6), z . u6), u6 = w6 normal to w5; z's dot
    # products with constants are alpha, beta and gamma times constants.
    k5 = _q5_constants(geo)
    q5, c5, s5 = _atan2_cos_sin(alpha * k5[0] + beta * k5[1] + gamma * k5[2],
                                alpha * k5[3] + beta * k5[4] + gamma * k5[5])
    # q4 turns z onto tv about w4 (subproblem 1): u = z normal to w4 is
    # beta (w5 - s45 w4) + gamma n45, two orthogonal parts, so |u| (the lever) has no
    # cancellation; atan2((w4 x u) . tv, u . tv).
    a4, a5, an, am = (x[..., None] for x in (a4, a5, an, am))
    lever = np.sqrt((beta ** 2 + gamma ** 2) * nn45)
    q4, c4, s4 = _atan2_cos_sin(beta * an + gamma * am, beta * (a5 - s45 * a4) + gamma * an)
    singular = lever < 1e-9
    if singular.any():
        ref4 = np.broadcast_to(q_ref[:, None, None, None, 3], q4.shape)
        q4 = np.where(singular, ref4, q4)
        c4 = np.where(singular, np.cos(ref4), c4)
        s4 = np.where(singular, np.sin(ref4), s4)
    # q6: Rot6 x6 = Rot5^T Rot4^T R_w x6, of which only two dot products are needed (see
    # _q6_basis): products of tx with constants, then of sin and cos of q4 and q5.
    d = _dots(goal[..., 1, None, :], B[:, 4:])                                # (m, 2, 2, 1) each
    h = [d[3 * i] + c5 * d[3 * i + 1] + s5 * d[3 * i + 2] for i in range(6)]
    q6 = np.arctan2(h[0] + c4 * h[1] + s4 * h[2], h[3] + c4 * h[4] + s4 * h[5])
    ok = ok1[:, None, None, None] & ok3[:, :, None, None] & ok_w[..., None]
    used_ref = shoulder | (lever < 1e-9).reshape(m, -1).any(axis=1)
    return (q1_pair, q2, q3, q4, q5, q6), np.broadcast_to(ok, q4.shape), used_ref


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
                         chunk: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """
    Solve many poses at once: ``T`` (m, 4, 4) -> ``(Q (m, 8, 6), valid (m, 8))``.

    ``Q[k, b]`` is branch ``b`` of pose ``k`` [rad]; ``valid`` marks the branches that reproduce
    the pose by FK within ``tol`` ([m] and [rad]) and, with ``within_limits``, respect the joint
    limits. Poses are checked for shape and finiteness only (no orthonormality test: use
    ``ik_closed_form`` for one untrusted pose). ``q_ref`` (6,) or (m, 6) picks q1 and q4 at
    shoulder and wrist singularities. Raises ``InvalidInputError`` for arms the closed form
    does not cover. ``chunk`` poses are solved at a time (cache-sized blocks).
    """
    geo = wrist_geometry(arm)
    T = as_finite_array(T, (None, 4, 4), 'poses')
    m = len(T)
    q_ref = _as_q_ref(arm, q_ref, m)
    Q = np.empty((m, N_BRANCHES, 6))
    ok = np.empty((m, N_BRANCHES), dtype=bool)
    for lo in range(0, m, chunk):
        sl = slice(lo, lo + chunk)
        Q[sl], ok[sl] = solve_candidates(arm, geo, T[sl], q_ref[sl], within_limits, tol)
    return Q, ok


def solve_candidates(arm: ArmModel, geo: WristGeometry, T: np.ndarray, q_ref: np.ndarray,
                     within_limits: bool = True, tol: float = VERIFY_TOL,
                     return_ref_used: bool = False) -> tuple[np.ndarray, ...]:
    """
    Return the 8 candidates (m, 8, 6) of poses ``T`` (m, 4, 4) and the mask of verified ones.

    The unchecked core of ``ik_closed_form_batch`` for callers that solve pose after pose:
    ``geo`` from ``wrist_geometry(arm)``, ``q_ref`` (m, 6) already validated. With
    ``return_ref_used`` a third array (m,) marks the singular poses whose q1 or q4 came from
    ``q_ref``.
    """
    joints, ok, used_ref = _candidates(geo, T, q_ref)
    m = len(T)
    # Each joint aliased nearest q_ref (and into its limits) once per branch it depends on
    # (``nearest_alias`` joint by joint: the same numbers), then spread over the 8 branches.
    Q = np.empty((m, 2, 2, 2, 6))
    for j, q in enumerate(joints):
        ref = q_ref[:, j].reshape((m,) + (1,) * (q.ndim - 1))
        q = ref + _wrap(q - ref)
        spread = q.shape + (1,) * (4 - q.ndim)
        if within_limits:
            lo, hi = arm.lower[j], arm.upper[j]
            q = _into_range(q, lo, hi)
            ok = ok & ((q >= lo - 1e-9) & (q <= hi + 1e-9)).reshape(spread)
        Q[..., j] = q.reshape(spread)
    Q = Q.reshape(m, N_BRANCHES, 6)
    ok = np.array(ok).reshape(m, N_BRANCHES)   # writable: the FK check fills it in place
    # FK check of the candidates still in question (often half of them or fewer), on squared
    # figures (no roots): |dp|^2 < tol^2 and the rotation chord
    # |R - R_goal|_F^2 = 8 sin^2(angle / 2) < 8 sin^2(tol / 2).
    flat = np.flatnonzero(ok)
    if len(flat):
        diff = (fk_batch(arm, Q.reshape(-1, 6)[flat])[:, :3]
                - T[flat // N_BRANCHES, :3])
        sq = diff * diff
        ok.reshape(-1)[flat] = ((sq[..., 3].sum(-1) < tol ** 2)
                                & (sq[..., :3].sum((-2, -1)) < 8.0 * np.sin(tol / 2.0) ** 2))
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
    from mover6_control.kinematics.ik_one_pose import ik_one_pose  # it builds on this module

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
