"""
Inverse kinematics along a path of poses: one continuous branch, or a reason why not.

For each waypoint the solution closest to the previous one (the first: to ``q_start``) is
taken, in the max-norm of the joint step. Closed form first (every branch, so the continuous one
is always among them); numeric IK seeded with the previous solution for arms without a
spherical wrist, and as a fallback when the closed form finds nothing. A path never switches
branch: a step larger than ``max_joint_step`` is a discontinuity and fails the path (reason
'joint_limits' instead when the branch itself goes on, but outside the joint limits). Near a
singularity (Jacobian condition number above ``max_condition`` and rising, i.e. moving towards
it) the path fails too: leaving a singular pose, such as the Mover6's home (q5 = 0, axes 4 and
6 aligned), is allowed. Leaving it may need q4 and q6 turned against each other first; when a
step is too large and the previous waypoint can be re-chosen on its own pose by such a
self-motion (the tool stays still, checked by FK along the joint segment), it is, and
``PathSolution.self_motion`` marks that step.

A step larger than ``max_joint_step`` between two waypoints is not yet a discontinuity when the
caller can give the poses between them (``pose_between``: the path's own curve): the stretch is
then followed more finely, the nearest branch at each intermediate pose, halving the stride
where a step is still too large, down to ``BRIDGE_RESOLUTION`` [m] and ``BRIDGE_ANGLE`` [rad]
between poses. When it gets through, the intermediate waypoints are inserted (the controller
interpolates in joint space between waypoints, so a large joint step would leave the Cartesian
path in between) and ``PathSolution.inserted`` marks them; a step still too large at that
resolution is a real discontinuity (a branch flip) and is refused.

Speed: every waypoint's closed-form branches are found in one batch. For arms whose joints all
turn less than a full turn (``single_turn``) a branch's joint values do not depend on the
waypoint it is compared with, so every step between the branches of neighbouring waypoints is
computed at once (``branch_steps``) and the branch choice is a walk over a small integer
table; singular waypoints, numeric fallbacks and steps over the limit take the waypoint-by-
waypoint way, which gives the same choice.

Failures raise ``UnreachableError`` (made in ``kinematics.unreachable``) with ``reason`` in
``errors.REASONS`` and ``details`` holding 'waypoint', 'position_error' [m],
'orientation_error' [rad], 'closest_q' and 'closest_pose' (the nearest configuration found
inside the joint limits and its pose), plus 'message'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mover6_control.errors import InvalidInputError, NotATransformError
from mover6_control.kinematics.forward import condition_number, fk_batch, jacobian_batch
from mover6_control.kinematics.ik_closed_form import (nearest_alias, pose_errors_batch,
                                                      solve_candidates)
from mover6_control.kinematics.ik_numeric import DEFAULT_WEIGHTS, ik_numeric
from mover6_control.kinematics.rotations import pose_error
from mover6_control.kinematics.unreachable import path_failure, unreachable_error
from mover6_control.kinematics.wrist import VERIFY_TOL, wrist_geometry
from mover6_control.validation import as_finite_array, as_positive
from mover6_control.values import ORTHONORMAL_TOL
import numpy as np

if TYPE_CHECKING:
    from collections.abc import Callable

    from mover6_control.kinematics.arm import ArmModel

# Finest pose spacing [m], [rad] at which a too-large joint step is still looked into: a
# continuous branch changes by far less than max_joint_step over it.
BRIDGE_RESOLUTION = 1e-3
BRIDGE_ANGLE = 1e-3


@dataclass(frozen=True)
class PathSolution:
    """Joint waypoints for a pose path and per-waypoint figures."""

    q: np.ndarray                  # (m, n) [rad]
    position_error: np.ndarray     # (m,) [m], FK of q against the poses
    orientation_error: np.ndarray  # (m,) [rad]
    condition: np.ndarray          # (m,) Jacobian condition number at each waypoint
    joint_step: np.ndarray         # (m,) largest joint change from the previous waypoint [rad]
    method: str                    # 'closed_form' or 'numeric'
    # (m,) True where the step into a waypoint keeps the tool still (joints re-arranged at a
    # singular pose: q4 against q6 at a wrist singularity).
    self_motion: np.ndarray = None
    # (m, 4, 4) the pose of each row (the given poses, plus any inserted between them) and
    # (m,) True for the inserted rows.
    poses: np.ndarray = None
    inserted: np.ndarray = None

    @property
    def max_joint_step(self) -> float:
        """Return the largest joint change between neighbouring waypoints [rad]."""
        return float(self.joint_step.max())

    @property
    def max_condition(self) -> float:
        """Return the largest Jacobian condition number along the path."""
        return float(self.condition.max())


def validate_poses(poses: np.ndarray, name: str = 'poses') -> np.ndarray:
    """Return ``poses`` as a (m, 4, 4) array of proper transforms (m >= 1) or raise."""
    P = as_finite_array(poses, (None, 4, 4), name)
    if len(P) == 0:
        raise InvalidInputError(f'{name} is empty')
    R = P[:, :3, :3]
    err = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero(err > ORTHONORMAL_TOL)
    if len(bad):
        raise NotATransformError(
            f'{name}[{bad[0]}] rotation is not orthonormal (|R^T R - I| = {err[bad[0]]:.2e})')
    bad = np.flatnonzero(np.linalg.det(R) < 0.0)
    if len(bad):
        raise NotATransformError(f'{name}[{bad[0]}] rotation is a reflection (det < 0)')
    bad = np.flatnonzero(np.abs(P[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > ORTHONORMAL_TOL)
    if len(bad):
        raise NotATransformError(f'{name}[{bad[0]}] last row must be [0, 0, 0, 1]')
    return P


def single_turn(arm: ArmModel) -> bool:
    """
    Return True when no joint's range reaches a full turn (with the 1e-9 rad limit slack).

    Each joint angle then has at most one value by whole turns inside its limits, so a closed-
    form branch has the same joint values whichever waypoint it is aliased against.
    """
    return bool(np.all(arm.upper - arm.lower < 2.0 * np.pi - 4e-9))


def branch_steps(arm: ArmModel, Q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """
    Return every step between the branches of neighbouring waypoints (m - 1, b, b) [rad].

    ``Q`` (m, b, n) [rad] are the closed-form branches of m waypoints inside the limits of a
    ``single_turn`` arm and ``valid`` (m, b) the verified ones. ``steps[k, a, c]`` is the
    max-norm joint change from branch a of waypoint k to branch c of waypoint k + 1, inf where
    branch c is not valid. It is what aliasing c nearest a (``nearest_alias``) would give: a
    single-turn joint has one value inside its limits, except that a value within the 1e-9 rad
    slack outside a limit and more than half a turn away is not brought back (inf too).
    """
    Q = np.asarray(Q, dtype=float)
    valid = np.asarray(valid, dtype=bool)
    if Q.ndim != 3 or Q.shape[2] != arm.n_joints or valid.shape != Q.shape[:2]:
        raise InvalidInputError(
            f'branches must be (m, b, {arm.n_joints}) with a (m, b) mask, got {Q.shape} and '
            f'{valid.shape}')
    if not single_turn(arm):
        raise InvalidInputError(f'{arm.name} has a joint with a full turn of range or more: '
                                'its branches depend on the previous waypoint')
    # Joint by joint into preallocated (m - 1, b, b) buffers: small arrays stay in cache.
    Qj = np.ascontiguousarray(Q.transpose(2, 0, 1))                  # (n, m, b)
    slack = (Qj[:, 1:] < arm.lower[:, None, None]) | (Qj[:, 1:] > arm.upper[:, None, None])
    steps = np.zeros((len(Q) - 1, Q.shape[1], Q.shape[1]))
    diff = np.empty_like(steps)
    far = np.zeros(steps.shape, dtype=bool)
    for i in range(arm.n_joints):
        np.subtract(Qj[i, 1:, None, :], Qj[i, :-1, :, None], out=diff)
        np.abs(diff, out=diff)
        np.maximum(steps, diff, out=steps)
        if slack[i].any():
            far |= (diff > np.pi) & slack[i, :, None, :]
    steps[far | ~valid[1:, None, :]] = np.inf
    return steps


def solve_path(arm: ArmModel, poses: np.ndarray, q_start: np.ndarray, *,
               max_joint_step: float = 0.35, max_condition: float | None = None,
               position_tol: float = 1e-3, orientation_tol: float = 0.01,
               weights: Sequence[float] = DEFAULT_WEIGHTS,
               pose_between: Callable[[int, np.ndarray], np.ndarray] | None = None
               ) -> PathSolution:
    """
    Return a ``PathSolution`` for ``poses`` (m, 4, 4) starting from ``q_start`` (n,) [rad].

    ``pose_between(k, s)``, when given, returns the path's poses (len(s), 4, 4) at fractions
    ``s`` in [0, 1] of the way from the previous pose (for k = 0 the pose of ``q_start``) to
    ``poses[k]``; a too-large step is then followed more finely before it is refused (see the
    module docstring), and the returned solution may have more rows than ``poses``.

    ``max_joint_step`` [rad] is the largest joint change allowed between neighbours;
    ``max_condition`` (None: no check) the largest Jacobian condition number allowed when moving
    towards a singularity; ``position_tol`` [m] and ``orientation_tol`` [rad] the accuracy
    each waypoint must reach. Raises ``UnreachableError`` (see the module docstring) or
    ``InvalidInputError`` for bad input.
    """
    P = validate_poses(poses)
    q_prev = arm.check_q(q_start, 'q_start')
    max_joint_step = as_positive(max_joint_step, 'max_joint_step')
    max_condition = as_positive(max_condition, 'max_condition', allow_none=True)
    position_tol = as_positive(position_tol, 'position_tol')
    orientation_tol = as_positive(orientation_tol, 'orientation_tol')
    try:
        geometry = wrist_geometry(arm)
    except InvalidInputError:
        geometry = None
    m, n = len(P), arm.n_joints
    Q = np.empty((m, n))
    self_motion = np.zeros(m, dtype=bool)
    bridges = {}     # waypoint k -> (rows (r, n), poses (r, 4, 4)) inserted before it
    q_start_arr = q_prev
    stop = None      # the first failing waypoint: (reason, index, q, q_prev, step)
    state = None     # the branch of the previous waypoint when q_prev is its batch candidate
    walk = geometry is not None and m > 1 and single_turn(arm)
    if geometry is not None:
        # Every waypoint at once; the few singular ones (q1 or q4 free) are solved again below
        # with the previous waypoint as reference.
        all_cand, all_ok, all_used = solve_candidates(
            arm, geometry, P, np.broadcast_to(q_prev, (m, n)), True, VERIFY_TOL,
            return_ref_used=True)
        if walk:
            # Every step between branches of neighbouring waypoints at once; the walk below
            # then only looks up the nearest branch to the one taken before.
            table = branch_steps(arm, all_cand, all_ok)
            nearest = np.argmin(table, axis=2)
            nearest_step = np.take_along_axis(table, nearest[..., None], axis=2)[..., 0]
            # A branch is taken from the table when it is a regular waypoint's and the step
            # is allowed; anything else (singular pose, no branch, a jump) goes the long way.
            usable = ((nearest_step <= max_joint_step)
                      & ~all_used[1:, None] & ~all_used[:-1, None])
            # One flat list of small ints (-1: go the long way): no per-row Python objects.
            b = all_cand.shape[1]
            walk_to = np.where(usable, nearest, -1).ravel().tolist()
    # The rows the table walk takes, written into Q in one call before the long way reads Q
    # (and at the end): a row at a time cost a numpy call per waypoint.
    walked_k, walked_j = [], []
    for k in range(m):
        if state is not None:
            j = walk_to[(k - 1) * b + state]
            if j >= 0:
                walked_k.append(k)
                walked_j.append(j)
                state = j
                continue
        if walked_k:
            Q[walked_k] = all_cand[walked_k, walked_j]
            walked_k, walked_j = [], []
        q_prev = q_start_arr if k == 0 else Q[k - 1]
        T = P[k]
        sols = np.zeros((0, n))
        branch = np.zeros(0, dtype=int)
        if geometry is not None:
            cand, ok = all_cand[k:k + 1], all_ok[k:k + 1]
            if all_used[k]:
                cand, ok = solve_candidates(arm, geometry, T[None], q_prev[None], True,
                                            VERIFY_TOL)
            # Each joint's value by whole turns nearest the previous waypoint (the batch used
            # q_start as reference; this matters for joints with more than a turn of range).
            branch = np.flatnonzero(ok[0])
            sols = nearest_alias(arm, cand[0][branch], q_prev)
            inside = np.all((sols >= arm.lower - 1e-9) & (sols <= arm.upper + 1e-9), axis=1)
            sols, branch = sols[inside], branch[inside]
        if len(sols) == 0:
            sols = _numeric(arm, T, q_prev, position_tol, orientation_tol, weights, k)
            branch = np.full(len(sols), -1)
        if len(sols) == 0:
            stop = ('unreachable', k, None, q_prev, None)
            break
        steps = np.abs(sols - q_prev).max(axis=1)
        j = int(np.argmin(steps))
        if steps[j] > max_joint_step and k >= 1 and geometry is not None:
            before = q_start_arr if k == 1 else Q[k - 2]
            if k - 1 in bridges:
                before = bridges[k - 1][0][-1]   # (not on that pose: no re-choice there)
            redo = _self_motion_start(arm, geometry, P[k - 1], before, sols, steps,
                                      max_joint_step, position_tol, orientation_tol)
            if redo is not None:
                # Waypoint k - 1 is re-chosen on the same pose (the tool stays still while
                # the joints turn, e.g. q4 against q6 at a wrist singularity).
                q_prev, j = redo
                Q[k - 1] = q_prev
                self_motion[k - 1] = True
                steps = np.abs(sols - q_prev).max(axis=1)
        if steps[j] > max_joint_step and pose_between is not None:
            bridge = _bridge(arm, geometry, pose_between, k, q_prev, sols, max_joint_step,
                             (position_tol, orientation_tol, weights))
            if bridge is not None:
                rows, row_poses, j = bridge
                bridges[k] = (rows, row_poses)
                steps = np.abs(sols - rows[-1]).max(axis=1)
        q = sols[j]
        if steps[j] > max_joint_step:
            stop = ('discontinuity', k, q, q_prev, steps[j])
            break
        Q[k] = q
        # The table walk may resume from a regular waypoint's batch branch.
        state = int(branch[j]) if walk and branch[j] >= 0 and not all_used[k] else None
    if walked_k:
        Q[walked_k] = all_cand[walked_k, walked_j]
    # Singularity check on the rows solved so far (all at once): fail where the condition
    # number is above max_condition and rising, unless an earlier waypoint failed.
    k_end = m if stop is None else stop[1]
    # Every row in order: the inserted ones before the waypoint they lead to. None inserted
    # (the usual case): the rows are the waypoints', copied in one call each.
    if bridges and k_end:
        rows_q, rows_p, rows_k, rows_new = [], [], [], []
        for k in range(k_end):
            if k in bridges:
                rows_q.append(bridges[k][0])
                rows_p.append(bridges[k][1])
                rows_k.append(np.full(len(bridges[k][0]), k))
                rows_new.append(np.ones(len(bridges[k][0]), dtype=bool))
            rows_q.append(Q[k:k + 1])
            rows_p.append(P[k:k + 1])
            rows_k.append([k])
            rows_new.append([False])
        Q_all, P_all = np.concatenate(rows_q), np.concatenate(rows_p)
        k_all, new_all = np.concatenate(rows_k).astype(int), np.concatenate(rows_new)
    else:
        Q_all, P_all = Q[:k_end].copy(), P[:k_end].copy()
        k_all, new_all = np.arange(k_end), np.zeros(k_end, dtype=bool)
    cond = _condition_numbers(arm, Q_all)
    if max_condition is not None and k_end:
        before = np.concatenate([[condition_number(arm, q_start_arr)], cond[:-1]])
        bad = np.flatnonzero((cond > max_condition) & (cond > before * (1 + 1e-6)))
        if len(bad):
            r = int(bad[0])
            k = int(k_all[r])
            q_before = q_start_arr if r == 0 else Q_all[r - 1]
            where = f'the way to waypoint {k}' if new_all[r] else f'waypoint {k}'
            raise path_failure(arm, P_all[r], q_before, k, 'singularity',
                               f'{where} is near a singularity (Jacobian condition number '
                               f'{cond[r]:.3g} > {max_condition:.3g}, rising)',
                               {'condition': float(cond[r]), 'solution_q': Q_all[r].copy()})
    if stop is not None and stop[0] == 'unreachable':
        k, q_prev = stop[1], stop[3]
        raise unreachable_error(arm, P[k], q_prev, k, weights, geometry, what='waypoint')
    if stop is not None:
        _, k, q, q_prev, step = stop
        joint = int(np.argmax(np.abs(q - q_prev)))
        if geometry is not None:
            # The branch continues, but past a joint limit: that, not a branch switch, is why.
            cand, ok = solve_candidates(arm, geometry, P[k][None], q_prev[None], False,
                                        VERIFY_TOL)
            near = cand[0][ok[0]]
            near = near[np.abs(near - q_prev).max(axis=1) <= max_joint_step]
            over = arm.limit_violations(near[0]) if len(near) else []
            if over:
                raise path_failure(
                    arm, P[k], q_prev, k, 'joint_limits',
                    f'waypoint {k} continues the path only outside the joint limits ('
                    + '; '.join(over) + f'); inside them it needs a jump of {step:.3f} rad '
                    f'in {arm.joint_names[joint]}',
                    {'joint_step': float(step), 'joint': arm.joint_names[joint],
                     'jump_q': q, 'q_outside_limits': near[0]})
        raise path_failure(
            arm, P[k], q_prev, k, 'discontinuity',
            f'waypoint {k} needs a jump of {step:.3f} rad in {arm.joint_names[joint]} '
            f'(limit {max_joint_step:.3f} rad): the continuous branch does not reach it',
            {'joint_step': float(step), 'joint': arm.joint_names[joint], 'jump_q': q})
    # Every solution was verified when found (closed form to VERIFY_TOL, numeric to the
    # tolerances); the figures are measured again here on the final joint path.
    pos, rot = pose_errors_batch(P_all, fk_batch(arm, Q_all))
    step = np.abs(np.diff(np.vstack([q_start_arr, Q_all]), axis=0)).max(axis=1)
    return PathSolution(q=Q_all, position_error=pos, orientation_error=rot, condition=cond,
                        joint_step=step,
                        method='closed_form' if geometry is not None else 'numeric',
                        self_motion=self_motion[k_all] & ~new_all, poses=P_all,
                        inserted=new_all)


def holds_pose(arm: ArmModel, q_a: np.ndarray, q_b: np.ndarray, T: np.ndarray,
               position_tol: float, orientation_tol: float, samples: int = 11) -> bool:
    """Return True when the joint-space segment ``q_a`` -> ``q_b`` keeps the tool at ``T``."""
    s = np.linspace(0.0, 1.0, samples)[:, None]
    poses = fk_batch(arm, q_a + s * (q_b - q_a))
    pos, rot = pose_errors_batch(np.broadcast_to(T, poses.shape), poses)
    return bool(np.all(pos <= position_tol) and np.all(rot <= orientation_tol))


def _self_motion_start(arm, geometry, T_prev, before, sols, steps, max_joint_step,
                       position_tol, orientation_tol):
    """
    Re-choose the previous waypoint on its own pose so that the next one is a small step.

    Allowed only when the joints can move from ``before`` to the new choice without moving the
    tool (self-motion: at a wrist singularity q4 and q6 turn against each other). This lets a
    path leave a singular start, such as the Mover6's home, towards any orientation. Returns
    (new previous configuration, index into ``sols``) or None.
    """
    for j in np.argsort(steps):
        cand, ok = solve_candidates(arm, geometry, T_prev[None], sols[j][None], True, VERIFY_TOL)
        alts = cand[0][ok[0]]
        if len(alts) == 0:
            continue
        alt = alts[np.argmin(np.abs(alts - sols[j]).max(axis=1))]
        if (np.abs(sols[j] - alt).max() <= max_joint_step
                and holds_pose(arm, before, alt, T_prev, position_tol, orientation_tol)):
            return alt, int(j)
    return None


def _numeric(arm, T, q_prev, position_tol, orientation_tol, weights, k):
    """
    Return the numeric IK solution (1, n) of ``T`` seeded at ``q_prev``, or (0, n).

    The solver for arms without a closed form, and the fallback for poses the closed form
    misses by rounding (a fully stretched arm, say).
    """
    res = ik_numeric(arm, T, q_prev, position_tol=min(position_tol, 1e-6),
                     orientation_tol=min(orientation_tol, 1e-6), weights=weights, rng=k)
    return res.q[None] if res.success else np.zeros((0, arm.n_joints))


def _branches(arm, geometry, T, q_ref, tolerances, k):
    """Return the solutions (b, n) of ``T`` inside the limits, aliased nearest ``q_ref``."""
    if geometry is not None:
        cand, ok = solve_candidates(arm, geometry, T[None], q_ref[None], True, VERIFY_TOL)
        sols = nearest_alias(arm, cand[0][ok[0]], q_ref)
        sols = sols[np.all((sols >= arm.lower - 1e-9) & (sols <= arm.upper + 1e-9), axis=1)]
        if len(sols):
            return sols
    return _numeric(arm, T, q_ref, *tolerances, k)


def _bridge(arm, geometry, pose_between, k, q_prev, sols, max_joint_step, tolerances):
    """
    Follow the path from ``q_prev`` to waypoint ``k`` more finely; None when it jumps.

    Walks the fraction s from 0 to 1 taking at each pose the branch nearest the last one; a
    stride whose step exceeds ``max_joint_step`` is halved, one that passes is doubled next.
    The stretch is discontinuous when a step is still too large between poses closer than
    ``BRIDGE_RESOLUTION`` and ``BRIDGE_ANGLE``. Returns (rows (r, n), their poses (r, 4, 4),
    the index in ``sols`` of the branch reached at waypoint k).
    """
    s, stride, q = 0.0, 0.5, q_prev
    T_here = pose_between(k, np.zeros(1))[0]
    rows, poses = [], []
    while True:
        s_next = min(1.0, s + stride)
        T_next = pose_between(k, np.array([s_next]))[0]
        cand = nearest_alias(arm, sols, q) if s_next >= 1.0 else _branches(
            arm, geometry, T_next, q, tolerances, k)
        if len(cand):
            steps = np.abs(cand - q).max(axis=1)
            j = int(np.argmin(steps))
            if steps[j] <= max_joint_step:
                if s_next >= 1.0:
                    return (np.array(rows), np.array(poses), j) if rows else None
                q, s, T_here = cand[j], s_next, T_next
                rows.append(q)
                poses.append(T_next)
                stride *= 2.0
                continue
        pos, rot = pose_error(T_here, T_next)
        if (pos < BRIDGE_RESOLUTION and rot < BRIDGE_ANGLE) or s_next - s < 1e-9:
            return None    # (the second: the path itself jumps there)
        stride = 0.5 * (s_next - s)


def _condition_numbers(arm, Q):
    """Return the Jacobian condition numbers (m,) of configurations ``Q`` (m, n)."""
    if len(Q) == 0:
        return np.zeros(0)
    sv = np.linalg.svd(jacobian_batch(arm, Q), compute_uv=False)
    with np.errstate(divide='ignore'):
        return np.where(sv[:, -1] > 0.0, sv[:, 0] / sv[:, -1], np.inf)
