"""
Closed-form inverse kinematics of 6R arms with a spherical wrist: every solution, in batches.

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

This module prepares the constants of an arm (``_plan``: what is linear in the pose, the elbow
and wrist bases; ``_fk_chain``: the chain for the FK check) and checks the inputs; the steps
themselves, per pose, run compiled (numba) in ``ik_batch_kernel``: as array operations they
cost about 1 us a pose in interpreter overhead and temporaries, compiled about 0.5 us.
The one-pose ``ik_closed_form`` runs the same steps on Python floats
(``ik_one_pose``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

from mover6_control.kinematics.ik_batch_kernel import solve_poses
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

    row_nnz: np.ndarray    # (27,): per-pose rows, linear in the pose's top 12 entries: per row
    row_cols: np.ndarray   # (27, 12): its number of nonzero entries, their columns (in order)
    row_vals: np.ndarray   # (27, 12): and their values (a zero entry adds nothing to the sum)
    offset: np.ndarray     # (27,): their constant parts
    k: np.ndarray          # (15,): q3's equation (phi3, rho3, safe rho3, (|e|^2 + |u|^2) / 2),
    #                        sigma, the wrist's s45, s56, s45^2 - 1, |n45|^2 and q5's constants
    elbow: np.ndarray      # (2, 3): the plane coordinates of x - r2 are k0 + cos q3 k1 + sin q3 k2
    w3: np.ndarray         # (3,): w3 in the basis (e1, e2, w2) of the elbow plane
    tv_basis: np.ndarray   # (4, 3): w4, w5, n45, w4 x n45 in that basis
    tx_basis: np.ndarray   # (18, 3): the columns of ``_q6_basis`` in that basis


@lru_cache(maxsize=16)             # a WristGeometry is immutable and hashed by identity
def _plan(geo: WristGeometry) -> _Plan:
    """
    Return the constants of the batch solver for ``geo``.

    Everything the solver needs of a pose before any joint is known is linear in the pose's
    top 12 entries (with a constant part): 27 rows,

    - 0-2: q1's equation ``a cos q1 + b sin q1 = c``;
    - 3-8: the wrist centre seen from axis 2 after turning back by q1, in the plane normal to
      w2 with the basis (e1, e2): ``d = D0 + cos q1 D1 + sin q1 D2`` for each of e1, e2;
    - 9-26: the goal's axes ``g`` (R_goal M^T w6 and R_goal M^T x6) turned back by q1, in the
      basis (e1, e2, w2): ``g . Rot(w1, q1) b = g . b_par + cos q1 g . b_perp
      + sin q1 g . (w1 x b)`` for b = e1, e2, w2.

    ``sigma`` is +-1 when w3 = sigma w2 exactly (q2 and q3 then turn about one axis), else 0
    (a turn about w3 in full).
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
    k = (float(np.arctan2(b3, a3)), float(rho3), float(rho3 if rho3 > 1e-12 else 1.0),
         float((np.dot(e, e) + np.dot(u, u)) / 2.0), sigma, s45, s56, den,
         float(np.dot(n45, n45))) + _q5_constants(geo)
    rows = np.array(rows)
    row_nnz = np.count_nonzero(rows, axis=1)
    row_cols = np.zeros(rows.shape, dtype=np.int64)
    row_vals = np.zeros(rows.shape)
    for r, row in enumerate(rows):
        cols = np.flatnonzero(row)
        row_cols[r, :len(cols)], row_vals[r, :len(cols)] = cols, row[cols]
    plan = _Plan(row_nnz=row_nnz.astype(np.int64), row_cols=row_cols, row_vals=row_vals,
                 offset=np.array(offset), k=np.array(k, dtype=float),
                 elbow=np.ascontiguousarray(elbow), w3=basis @ w3,
                 tv_basis=np.ascontiguousarray((basis @ wb[:, :4]).T),
                 tx_basis=np.ascontiguousarray((basis @ wb[:, 4:]).T))
    for a in (plan.row_nnz, plan.row_cols, plan.row_vals, plan.offset, plan.k, plan.elbow,
              plan.w3, plan.tv_basis, plan.tx_basis):
        a.setflags(write=False)
    return plan


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _fk_chain(arm: ArmModel) -> tuple:
    """
    Return the URDF chain of ``forward`` as the compiled FK check reads it (``ik_batch_kernel``).

    ``frames`` (7, 3, 4): each joint's origin, then the tool, top rows; ``identity`` (7,): the
    frames that do not turn; ``axis_index`` (6,): for a joint turning about a frame axis (+-x,
    y or z, as ``forward`` tells them apart) that axis, else -1; ``turns`` (6, 3, 3, 3): the
    turn of the other joints as ``Rot(axis, q) = (I + sin q K) + (1 - cos q) K K`` (Rodrigues:
    ``I``, ``K``, ``K K``), and for a frame axis its sign at ``turns[i, 1, j + 2, j + 1]``
    (indices mod 3).
    """
    frames = np.array([T[:3] for T in list(arm.origins) + [arm.tool]])
    identity = np.array([np.array_equal(F[:, :3], np.eye(3)) for F in frames])
    turns = np.zeros((arm.n_joints, 3, 3, 3))
    axis_index = np.full(arm.n_joints, -1, dtype=np.int64)
    for i, axis in enumerate(arm.axes.tolist()):
        j = int(np.argmax(np.abs(axis)))
        if abs(abs(axis[j]) - 1.0) < 1e-15 and sum(abs(x) for x in axis) == abs(axis[j]):
            turns[i, 1, (j + 2) % 3, (j + 1) % 3] = 1.0 if axis[j] > 0.0 else -1.0
            axis_index[i] = j
        else:
            K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                          [-axis[1], axis[0], 0.0]])
            turns[i] = np.eye(3), K, K @ K
    for a in (frames, identity, turns, axis_index):
        a.setflags(write=False)
    return frames, turns, identity, axis_index


def _solve(arm, geo, T, q_ref, within_limits, tol, Q, ok):
    """
    Fill ``Q`` (m, 8, 6) and ``ok`` (m, 8) for poses ``T`` (m, 4, 4); return the used-ref mask.

    The steps of the module docstring, per pose in the compiled loop of ``ik_batch_kernel``: a
    branch whose joint is unsolvable or (with ``within_limits``) outside its limits is dropped
    as soon as that joint is known, before the joints after it are solved, and keeps
    ``q_ref``'s values in ``Q``. Branch ``shoulder * 4 + elbow * 2 + wrist flip``.
    """
    plan = _plan(geo)
    used_ref = np.empty(len(T), dtype=bool)
    solve_poses(np.ascontiguousarray(T, dtype=np.float64),
                np.ascontiguousarray(q_ref, dtype=np.float64), plan.row_nnz, plan.row_cols,
                plan.row_vals, plan.offset, plan.k, plan.elbow, plan.w3, plan.tv_basis,
                plan.tx_basis, _limits(arm, 'lower'), _limits(arm, 'upper'), *_fk_chain(arm),
                bool(within_limits), float(tol) ** 2, 8.0 * float(np.sin(tol / 2.0)) ** 2, Q, ok,
                used_ref)
    return used_ref


def _limits(arm, which):
    """Return the arm's ``lower`` or ``upper`` limits as a C-contiguous float64 array."""
    return np.ascontiguousarray(getattr(arm, which), dtype=np.float64)


@lru_cache(maxsize=16)             # an ArmModel is immutable and hashed by identity
def _geometry(arm: ArmModel) -> WristGeometry:
    """Return the arm's ``WristGeometry``, made once per arm (``_plan`` is cached by it)."""
    return wrist_geometry(arm)


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
    solved per call of the compiled loop (``ik_batch_kernel``).
    """
    geo = _geometry(arm)
    T = as_finite_array(T, (None, 4, 4), 'poses')
    m = len(T)
    q_ref = _as_q_ref(arm, q_ref, m)
    Q = np.empty((m, N_BRANCHES, 6))
    ok = np.empty((m, N_BRANCHES), dtype=bool)
    for lo in range(0, m, max(int(chunk), 1)):
        sl = slice(lo, lo + max(int(chunk), 1))
        _solve(arm, geo, T[sl], q_ref[sl], within_limits, tol, Q[sl], ok[sl])
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
    used_ref = _solve(arm, geo, T, q_ref, within_limits, tol, Q, ok)
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
