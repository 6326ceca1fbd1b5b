"""
Numeric inverse kinematics for any serial arm: damped least squares with joint limits, restarts.

The cost is the Mover6 report's eq. 21, a weighted sum of squared pose errors, ``e^T W e`` with
``e = [p_goal - p; log(R_goal R^T)]`` (metres, then a rotation vector in radians, base frame),
minimised inside the joint limits (eq. 22). The rotation vector replaces the report's Euler-angle
differences, which jump by 2 pi and are singular at B = +-pi/2 (exactly its example goal).

Steps are Levenberg-Marquardt with error-dependent damping (Sugihara 2011):
``(J^T W J + (c E + lambda_0) I) dq = J^T W e``, ``E = e^T W e / 2``, then projected onto
the joint limits (a joint held at a limit that the step pushes outwards leaves the active set;
a joint whose range spans a full turn wraps around instead).
The first start, ``q0``, runs alone first (``ik_first_start``, on floats: most poses end
there); if it stalls, ``n_seeds`` starts run side by side as one batch (the first is ``q0``,
the others random in the limits), and a start that stalls is re-seeded at random. The first
start that meets both tolerances wins; otherwise the lowest-cost configuration seen is
returned with ``success = False`` (the closest pose found).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.ik_first_start import first_start
from mover6_control.kinematics.rotations import rotation_log_batch, validate_transform
from mover6_control.validation import as_finite_array
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

DEFAULT_WEIGHTS = (1.0, 1.0, 1.0, 0.01, 0.01, 0.01)  # 1 rad weighs as 0.1 m
_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0
_LEVI_CIVITA.setflags(write=False)


@dataclass(frozen=True)
class NumericIKResult:
    """Outcome of ``ik_numeric``: ``q`` (n,) [rad] and how well it meets the pose."""

    q: np.ndarray
    success: bool
    position_error: float      # [m]
    orientation_error: float   # [rad]
    iterations: int            # batched iterations run
    restarts: int              # random re-seeds used after the first batch of starts
    cost: float                # weighted cost e^T W e at q


@dataclass(frozen=True, eq=False)
class ScrewChain:
    """
    Product-of-exponentials form of an arm, precomputed for fast small-batch FK and Jacobians.

    Joint i at angle q moves points by ``I + sin(q) A_i + (1 - cos(q)) B_i`` (4, 4), with
    ``A_i = [[K_i, -K_i r_i], [0, 0]]``, ``B_i = [[K_i^2, -K_i^2 r_i], [0, 0]]``, ``K_i`` the
    cross-product matrix of the space-frame axis ``omega_i`` and ``r_i`` a point on it (q = 0).
    """

    A: np.ndarray       # (n, 4, 4)
    B: np.ndarray       # (n, 4, 4)
    axis_point: np.ndarray  # (n, 4, 2) columns [omega_i; 0] and [r_i; 1]
    M: np.ndarray       # (4, 4) tip pose at q = 0


def screw_chain(arm: ArmModel) -> ScrewChain:
    """Return the ``ScrewChain`` of ``arm`` (one FK at q = 0)."""
    n = arm.n_joints
    frames = np.empty((n + 1, 4, 4))   # at q = 0 every joint rotation is the identity
    frames[0] = arm.origins[0]
    for i in range(1, n):
        frames[i] = frames[i - 1] @ arm.origins[i]
    frames[n] = frames[n - 1] @ arm.tool
    omega = np.einsum('nij,nj->ni', frames[:n, :3, :3], arm.axes)
    r = frames[:n, :3, 3]
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -omega[:, 2], omega[:, 1]
    K[:, 1, 0], K[:, 1, 2] = omega[:, 2], -omega[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -omega[:, 1], omega[:, 0]
    KK = K @ K
    A = np.zeros((n, 4, 4))
    B = np.zeros((n, 4, 4))
    A[:, :3, :3], A[:, :3, 3] = K, -np.einsum('nij,nj->ni', K, r)
    B[:, :3, :3], B[:, :3, 3] = KK, -np.einsum('nij,nj->ni', KK, r)
    axis_point = np.zeros((n, 4, 2))
    axis_point[:, :3, 0], axis_point[:, :3, 1], axis_point[:, 3, 1] = omega, r, 1.0
    return ScrewChain(A=A, B=B, axis_point=axis_point, M=frames[n])


def pose_residual_batch(chain: ScrewChain, Q: np.ndarray,
                        T_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return errors (m, 6) ``[p_goal - p; log(R_goal R^T)]`` and Jacobians (m, 6, n) at ``Q``.

    The Jacobian is the geometric one (rows [v; w], base frame, as ``forward.jacobian``);
    to first order ``e(q + dq) = e(q) - J dq``. Uses the screws of ``chain`` (a
    ``ScrewChain``), made for small batches in a tight loop.
    """
    m, n = Q.shape
    G = (np.eye(4) + np.sin(Q)[:, :, None, None] * chain.A
         + (1.0 - np.cos(Q))[:, :, None, None] * chain.B)
    C = np.empty_like(G)
    C[:, 0] = G[:, 0]
    for i in range(1, n):
        C[:, i] = C[:, i - 1] @ G[:, i]
    tip = C[:, n - 1] @ chain.M
    zo = C[:, :, :3] @ chain.axis_point            # (m, n, 3, 2): current axis and point
    z = zo[..., 0]
    lever = tip[:, None, :3, 3] - zo[..., 1]
    J = np.empty((m, 6, n))
    J[:, :3] = np.einsum('ijk,mnj,mnk->min', _LEVI_CIVITA, z, lever)   # z x lever
    J[:, 3:] = z.transpose(0, 2, 1)
    e = np.empty((m, 6))
    e[:, :3] = T_goal[:3, 3] - tip[:, :3, 3]
    e[:, 3:] = rotation_log_batch(T_goal[:3, :3] @ tip[:, :3, :3].transpose(0, 2, 1))
    return e, J


@lru_cache(maxsize=32)             # an ArmModel is immutable and hashed by identity
def _limits(arm: ArmModel, within_limits: bool) -> tuple:
    """
    Return the bounds, the random starts' span and the joints that wrap, once per arm.

    ``lo``, ``hi``: the iterates' bounds (None without limits); the span of the random starts
    (low, high); the joints whose range spans a full turn (they wrap; None if there are none).
    """
    n = arm.n_joints
    if not within_limits:
        return None, None, np.full(n, -np.pi), np.full(n, np.pi), None
    lo = np.where(np.isfinite(arm.lower), arm.lower, -np.pi)
    hi = np.where(np.isfinite(arm.upper), arm.upper, np.pi)
    wraps = np.flatnonzero(hi - lo >= 2.0 * np.pi - 1e-9)
    for arr in (lo, hi, wraps):
        arr.setflags(write=False)
    return lo, hi, lo, hi, wraps if len(wraps) else None


_DEFAULT_WEIGHTS = np.array(DEFAULT_WEIGHTS)
_DEFAULT_WEIGHTS.setflags(write=False)


def _check_weights(weights):
    """Return positive weights (6,) or raise."""
    if weights is DEFAULT_WEIGHTS:
        return _DEFAULT_WEIGHTS
    w = as_finite_array(weights, (6,), 'weights')
    if np.any(w <= 0.0):
        raise InvalidInputError(f'weights must be positive, got {w.tolist()}')
    return w


def ik_numeric(arm: ArmModel, T: np.ndarray, q0: np.ndarray, *, position_tol: float = 1e-6,
               orientation_tol: float = 1e-6, weights: Sequence[float] = DEFAULT_WEIGHTS,
               within_limits: bool = True, n_seeds: int = 4, max_iterations: int = 300,
               stall_iterations: int = 12, damping: float = 1e-9, error_damping: float = 0.1,
               max_step: float | None = None, n_candidates: int = 0,
               rng: int | np.random.Generator = 0) -> NumericIKResult:
    """
    Solve ``T`` (4, 4) numerically from ``q0`` (n,) [rad]; return a ``NumericIKResult``.

    ``position_tol`` [m] and ``orientation_tol`` [rad] define success; ``weights`` (6,) weigh
    the squared errors (the Mover6 report eq. 21; position in [m], orientation in [rad]).
    ``within_limits`` keeps every iterate inside the joint limits (eq. 22). ``n_seeds`` starts
    run as one batch for at most ``max_iterations``; a start whose cost has not dropped by 1 %
    in ``stall_iterations`` is re-seeded. ``damping`` is the LM floor lambda_0 and
    ``error_damping`` the factor on E; ``max_step`` [rad], if set, caps each joint's step.
    ``n_candidates`` > ``n_seeds``: the random starts are the best of that many random
    configurations (one batched cost evaluation).
    ``rng`` is a seed or a ``numpy.random.Generator`` for the random starts (no hidden state).
    """
    T = validate_transform(T, 'pose')
    q0 = arm.check_q(q0, 'q0')
    w = _check_weights(weights)
    for name, value in (('position_tol', position_tol), ('orientation_tol', orientation_tol)):
        if not np.isfinite(value) or value <= 0.0:
            raise InvalidInputError(f'{name} must be a positive number, got {value}')
    if int(n_seeds) < 1 or int(max_iterations) < 1:
        raise InvalidInputError('n_seeds and max_iterations must be >= 1')
    lo, hi, span_lo, span_hi, full_turn = _limits(arm, bool(within_limits))
    n = arm.n_joints
    # The first start alone, on floats: most poses are solved by it (see ik_first_start).
    first = first_start(arm, T, q0, w, (position_tol, orientation_tol),
                        (lo, hi) if within_limits else None, full_turn, damping, error_damping,
                        max_step, int(max_iterations), int(stall_iterations))
    if first is not None:
        q, pos, rot, it, cost = first
        return NumericIKResult(q=q, success=True, position_error=pos, orientation_error=rot,
                               iterations=it, restarts=0, cost=cost)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    chain = screw_chain(arm)
    Q = np.empty((int(n_seeds), n))
    Q[0] = np.clip(q0, lo, hi) if within_limits else q0
    if n_seeds > 1 and n_candidates > n_seeds:
        # Keep q0 and the random candidates of lowest cost (one batched evaluation).
        cand = gen.uniform(span_lo, span_hi, (int(n_candidates), n))
        e, _ = pose_residual_batch(chain, cand, T)
        Q[1:] = cand[np.argsort((e * e) @ w)[:int(n_seeds) - 1]]
    else:
        Q[1:] = gen.uniform(span_lo, span_hi, (int(n_seeds) - 1, n))
    best_q, best_cost, best_err = Q[0].copy(), np.inf, (np.inf, np.inf)
    stall_cost = np.full(len(Q), np.inf)
    stall_count = np.zeros(len(Q), dtype=int)
    restarts = 0
    eye = np.eye(n)
    for it in range(1, int(max_iterations) + 1):
        e, J = pose_residual_batch(chain, Q, T)
        sq = e * e
        cost = sq @ w
        pos2 = sq[:, 0] + sq[:, 1] + sq[:, 2]
        rot2 = sq[:, 3] + sq[:, 4] + sq[:, 5]
        done = (pos2 < position_tol ** 2) & (rot2 < orientation_tol ** 2)
        k = int(np.argmin(cost))
        if cost[k] < best_cost:
            best_q, best_cost = Q[k].copy(), float(cost[k])
            best_err = (np.sqrt(pos2[k]), np.sqrt(rot2[k]))
        if done.any():
            k = int(np.flatnonzero(done)[np.argmin(cost[done])])
            return NumericIKResult(q=Q[k].copy(), success=True,
                                   position_error=float(np.sqrt(pos2[k])),
                                   orientation_error=float(np.sqrt(rot2[k])), iterations=it,
                                   restarts=restarts, cost=float(cost[k]))
        JtW = J.transpose(0, 2, 1) * w
        A = JtW @ J + (error_damping * 0.5 * cost + damping)[:, None, None] * eye
        dq = np.linalg.solve(A, (JtW @ e[:, :, None]))[:, :, 0]
        if within_limits:
            # Active set: a joint at a limit that the step pushes outwards is held there and
            # the step is re-solved for the others (plain clipping stalls on the boundary).
            blocked = ((Q <= lo) & (dq < 0.0)) | ((Q >= hi) & (dq > 0.0))
            if full_turn is not None:
                blocked[:, full_turn] = False
            if blocked.any():
                Jf = J * ~blocked[:, None, :]
                JtW = Jf.transpose(0, 2, 1) * w
                A = JtW @ Jf + (error_damping * 0.5 * cost + damping)[:, None, None] * eye
                dq = np.linalg.solve(A, (JtW @ e[:, :, None]))[:, :, 0]
        if max_step is not None:
            dq *= np.minimum(1.0, max_step / (np.abs(dq).max(axis=1) + 1e-300))[:, None]
        Q = Q + dq
        if full_turn is not None:
            # A joint whose range spans a full turn wraps around instead of stopping.
            Q[:, full_turn] = lo[full_turn] + (Q[:, full_turn] - lo[full_turn]) % (2.0 * np.pi)
        if within_limits:
            Q = np.clip(Q, lo, hi)
        improved = cost < 0.99 * stall_cost
        stall_cost[improved] = cost[improved]
        stall_count += 1
        stall_count[improved] = 0
        stalled = stall_count >= stall_iterations
        if stalled.any():
            Q[stalled] = gen.uniform(span_lo, span_hi, (int(stalled.sum()), n))
            stall_cost[stalled] = np.inf
            stall_count[stalled] = 0
            restarts += int(stalled.sum())
    e, _ = pose_residual_batch(chain, Q, T)
    cost = np.einsum('ki,i,ki->k', e, w, e)
    k = int(np.argmin(cost))
    if cost[k] < best_cost:
        best_q, best_cost = Q[k].copy(), float(cost[k])
        best_err = (np.linalg.norm(e[k, :3]), np.linalg.norm(e[k, 3:]))
    success = bool(best_err[0] < position_tol and best_err[1] < orientation_tol)
    return NumericIKResult(q=best_q, success=success, position_error=float(best_err[0]),
                           orientation_error=float(best_err[1]), iterations=int(max_iterations),
                           restarts=restarts, cost=best_cost)


def closest_within_limits(arm: ArmModel, T: np.ndarray, seeds: np.ndarray, *,
                          weights: Sequence[float] = DEFAULT_WEIGHTS, n_seeds: int = 4,
                          max_iterations: int = 300,
                          rng: int | np.random.Generator = 0) -> NumericIKResult:
    """
    Return the ``NumericIKResult`` with the lowest weighted cost from several starts.

    For a pose that cannot be reached this is the closest pose found inside the joint limits
    (closest in the ``weights`` sense of the Mover6 report eq. 21). ``seeds`` (k, n) are tried in
    turn, each with ``n_seeds`` - 1 random companions; an exact solution ends the search.
    """
    seeds = as_finite_array(seeds, (None, arm.n_joints), 'seeds')
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    best = None
    for q0 in seeds:
        res = ik_numeric(arm, T, q0, weights=weights, n_seeds=n_seeds,
                         max_iterations=max_iterations, rng=gen)
        if best is None or res.cost < best.cost:
            best = res
        if best.success:
            break
    return best
