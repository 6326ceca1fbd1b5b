"""
Inverse kinematics along a path of poses: one continuous branch, or a reason why not.

For each waypoint the solution closest to the previous one (the first: to ``q_start``) is
taken, in the max-norm of the joint step. Closed form first (every branch, so the continuous one
is always among them); numeric IK seeded with the previous solution for arms without a
spherical wrist, and as a fallback when the closed form finds nothing. A path never switches
branch: a step larger than ``max_joint_step`` is a discontinuity and fails the path. Near a
singularity (Jacobian condition number above ``max_condition`` and rising, i.e. moving towards
it) the path fails too: leaving a singular pose, such as the Mover6's home (q5 = 0, axes 4 and
6 aligned), is allowed. Leaving it may need q4 and q6 turned against each other first; when a
step is too large and the previous waypoint can be re-chosen on its own pose by such a
self-motion (the tool stays still, checked by FK along the joint segment), it is, and
``PathSolution.self_motion`` marks that step.

Failures raise ``UnreachableError`` with ``reason`` in ``REASONS`` and ``details`` holding
'waypoint', 'position_error' [m], 'orientation_error' [rad], 'closest_q' and 'closest_pose'
(the nearest configuration found inside the joint limits and its pose), plus 'message'.
"""

from dataclasses import dataclass

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.ik import (nearest_alias, pose_errors_batch, solve_candidates, VERIFY_TOL,
                               wrist_geometry)
from mover6_control.ik_numeric import closest_within_limits, DEFAULT_WEIGHTS, ik_numeric
from mover6_control.kinematics import condition_number, fk, fk_batch, jacobian_batch
from mover6_control.rotations import as_finite_array, ORTHONORMAL_TOL, pose_error
import numpy as np

REASONS = ('out_of_reach', 'joint_limits', 'singularity', 'discontinuity')


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

    @property
    def max_joint_step(self):
        """Return the largest joint change between neighbouring waypoints [rad]."""
        return float(self.joint_step.max())

    @property
    def max_moving_step(self):
        """Return the largest joint change on steps that move the tool [rad]."""
        moving = self.joint_step if self.self_motion is None else np.where(
            self.self_motion, 0.0, self.joint_step)
        return float(moving.max())

    @property
    def max_condition(self):
        """Return the largest Jacobian condition number along the path."""
        return float(self.condition.max())


def validate_poses(poses, name='poses'):
    """Return ``poses`` as a (m, 4, 4) array of proper transforms (m >= 1) or raise."""
    P = as_finite_array(poses, (None, 4, 4), name)
    if len(P) == 0:
        raise InvalidInputError(f'{name} is empty')
    R = P[:, :3, :3]
    err = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero(err > ORTHONORMAL_TOL)
    if len(bad):
        raise InvalidInputError(
            f'{name}[{bad[0]}] rotation is not orthonormal (|R^T R - I| = {err[bad[0]]:.2e})')
    bad = np.flatnonzero(np.linalg.det(R) < 0.0)
    if len(bad):
        raise InvalidInputError(f'{name}[{bad[0]}] rotation is a reflection (det < 0)')
    bad = np.flatnonzero(np.abs(P[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > ORTHONORMAL_TOL)
    if len(bad):
        raise InvalidInputError(f'{name}[{bad[0]}] last row must be [0, 0, 0, 1]')
    return P


def _positive(name, value, allow_none=False):
    """Check that a setting is a positive finite number (or None when allowed)."""
    if value is None and allow_none:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError) as err:
        raise InvalidInputError(f'{name} must be a number, got {value!r}') from err
    if not np.isfinite(value) or value <= 0.0:
        raise InvalidInputError(f'{name} must be positive and finite, got {value}')
    return value


def _closest(arm, T, seeds, weights):
    """Return (q, pose, position error, orientation error) of the closest in-limit config."""
    res = closest_within_limits(arm, T, seeds, weights=weights)
    pose = fk(arm, res.q)
    pos, rot = pose_error(pose, T)
    return res.q, pose, pos, rot


def unreachable_error(arm, T, q_seed, waypoint, weights=DEFAULT_WEIGHTS, geometry=None,
                      what='the pose'):
    """
    Return the ``UnreachableError`` for a pose with no solution inside the limits.

    Tells 'joint_limits' (solutions exist outside the limits; the message names the joints)
    from 'out_of_reach', and finds the closest pose inside the limits. ``what`` is 'waypoint'
    (the message then names its index) or a noun for the message.
    """
    if geometry is not None:
        Q, ok = solve_candidates(arm, geometry, T[None], q_seed[None], within_limits=False)
        outside = Q[0][ok[0]]
    else:
        res = ik_numeric(arm, T, q_seed, within_limits=False, rng=waypoint)
        outside = res.q[None] if res.success else np.zeros((0, arm.n_joints))
    seeds = [q_seed]
    if len(outside):
        # The unconstrained solution that needs the least limit violation.
        over = np.maximum(arm.lower - outside, 0.0) + np.maximum(outside - arm.upper, 0.0)
        best = outside[np.argmin(over.sum(axis=1))]
        seeds.append(np.clip(best, arm.lower, arm.upper))
    q, pose, pos, rot = _closest(arm, T, np.array(seeds), weights)
    closest = (f'closest pose inside the limits misses it by {pos * 1e3:.1f} mm and '
               f'{rot:.4f} rad')
    what = f'waypoint {waypoint}' if what == 'waypoint' else what
    if len(outside):
        reason = 'joint_limits'
        message = (f'{what} is reachable only outside the joint limits ('
                   + '; '.join(arm.limit_violations(best)) + f'); {closest}')
    else:
        reason = 'out_of_reach'
        message = f'{what} is out of reach; {closest}'
    details = {'waypoint': int(waypoint), 'position_error': pos, 'orientation_error': rot,
               'closest_q': q, 'closest_pose': pose, 'message': message}
    if len(outside):
        details['q_outside_limits'] = best
    return UnreachableError(message, reason=reason, details=details)


def solve_path(arm, poses, q_start, *, max_joint_step=0.35, max_condition=None,
               position_tol=1e-3, orientation_tol=0.01, weights=DEFAULT_WEIGHTS):
    """
    Return a ``PathSolution`` for ``poses`` (m, 4, 4) starting from ``q_start`` (n,) [rad].

    ``max_joint_step`` [rad] is the largest joint change allowed between neighbours;
    ``max_condition`` (None: no check) the largest Jacobian condition number allowed when moving
    towards a singularity; ``position_tol`` [m] and ``orientation_tol`` [rad] the accuracy
    each waypoint must reach. Raises ``UnreachableError`` (see the module docstring) or
    ``InvalidInputError`` for bad input.
    """
    P = validate_poses(poses)
    q_prev = arm.check_q(q_start, 'q_start')
    max_joint_step = _positive('max_joint_step', max_joint_step)
    max_condition = _positive('max_condition', max_condition, allow_none=True)
    position_tol = _positive('position_tol', position_tol)
    orientation_tol = _positive('orientation_tol', orientation_tol)
    try:
        geometry = wrist_geometry(arm)
    except InvalidInputError:
        geometry = None
    m, n = len(P), arm.n_joints
    out = {key: np.empty(m) for key in ('pos', 'rot', 'cond', 'step')}
    Q = np.empty((m, n))
    self_motion = np.zeros(m, dtype=bool)
    q_start_arr = q_prev
    stop = None      # the first failing waypoint: (reason, index, q, q_prev, step)
    if geometry is not None:
        # Every waypoint at once; the few singular ones (q1 or q4 free) are solved again below
        # with the previous waypoint as reference.
        all_cand, all_ok, all_used = solve_candidates(
            arm, geometry, P, np.broadcast_to(q_prev, (m, n)), True, VERIFY_TOL,
            return_ref_used=True)
    for k in range(m):
        T = P[k]
        sols = np.zeros((0, n))
        if geometry is not None:
            cand, ok = all_cand[k:k + 1], all_ok[k:k + 1]
            if all_used[k]:
                cand, ok = solve_candidates(arm, geometry, T[None], q_prev[None], True,
                                            VERIFY_TOL)
            # Each joint's value by whole turns nearest the previous waypoint (the batch used
            # q_start as reference; this matters for joints with more than a turn of range).
            sols = nearest_alias(arm, cand[0][ok[0]], q_prev)
            sols = sols[np.all((sols >= arm.lower - 1e-9) & (sols <= arm.upper + 1e-9), axis=1)]
        if len(sols) == 0:
            # Numeric IK: the solver for arms without a closed form, and the fallback for poses
            # the closed form misses by rounding (a fully stretched arm, say).
            res = ik_numeric(arm, T, q_prev, position_tol=min(position_tol, 1e-6),
                             orientation_tol=min(orientation_tol, 1e-6), weights=weights, rng=k)
            sols = res.q[None] if res.success else sols
        if len(sols) == 0:
            stop = ('unreachable', k, None, q_prev, None)
            break
        steps = np.abs(sols - q_prev).max(axis=1)
        j = int(np.argmin(steps))
        if steps[j] > max_joint_step and k >= 1 and geometry is not None:
            before = q_start_arr if k == 1 else Q[k - 2]
            redo = _self_motion_start(arm, geometry, P[k - 1], before, sols, steps,
                                      max_joint_step, position_tol, orientation_tol)
            if redo is not None:
                # Waypoint k - 1 is re-chosen on the same pose (the tool stays still while
                # the joints turn, e.g. q4 against q6 at a wrist singularity).
                q_prev, j = redo
                Q[k - 1] = q_prev
                out['step'][k - 1] = np.abs(q_prev - before).max()
                self_motion[k - 1] = True
                steps = np.abs(sols - q_prev).max(axis=1)
        q = sols[j]
        if steps[j] > max_joint_step:
            stop = ('discontinuity', k, q, q_prev, steps[j])
            break
        Q[k] = q
        out['step'][k] = steps[j]
        q_prev = q
    # Singularity check on the rows solved so far (all at once): fail where the condition
    # number is above max_condition and rising, unless an earlier waypoint failed.
    k_end = m if stop is None else stop[1]
    cond = _condition_numbers(arm, Q[:k_end])
    if max_condition is not None and k_end:
        before = np.concatenate([[condition_number(arm, q_start_arr)], cond[:-1]])
        bad = np.flatnonzero((cond > max_condition) & (cond > before * (1 + 1e-6)))
        if len(bad):
            k = int(bad[0])
            q_before = q_start_arr if k == 0 else Q[k - 1]
            _fail(arm, P[k], q_before, k, 'singularity',
                  f'waypoint {k} is near a singularity (Jacobian condition number '
                  f'{cond[k]:.3g} > {max_condition:.3g}, rising)',
                  {'condition': float(cond[k]), 'solution_q': Q[k].copy()})
    if stop is not None and stop[0] == 'unreachable':
        k, q_prev = stop[1], stop[3]
        raise unreachable_error(arm, P[k], q_prev, k, weights, geometry, what='waypoint')
    if stop is not None:
        _, k, q, q_prev, step = stop
        joint = int(np.argmax(np.abs(q - q_prev)))
        _fail(arm, P[k], q_prev, k, 'discontinuity',
              f'waypoint {k} needs a jump of {step:.3f} rad in {arm.joint_names[joint]} '
              f'(limit {max_joint_step:.3f} rad): the continuous branch does not reach it',
              {'joint_step': float(step), 'joint': arm.joint_names[joint], 'jump_q': q})
    out['cond'] = cond
    # Every solution was verified when found (closed form to VERIFY_TOL, numeric to the
    # tolerances); the figures are measured again here on the final joint path.
    out['pos'], out['rot'] = pose_errors_batch(P, fk_batch(arm, Q))
    return PathSolution(q=Q, position_error=out['pos'], orientation_error=out['rot'],
                        condition=out['cond'], joint_step=out['step'],
                        method='closed_form' if geometry is not None else 'numeric',
                        self_motion=self_motion)


def holds_pose(arm, q_a, q_b, T, position_tol, orientation_tol, samples=11):
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


def _condition_numbers(arm, Q):
    """Return the Jacobian condition numbers (m,) of configurations ``Q`` (m, n)."""
    if len(Q) == 0:
        return np.zeros(0)
    sv = np.linalg.svd(jacobian_batch(arm, Q), compute_uv=False)
    with np.errstate(divide='ignore'):
        return np.where(sv[:, -1] > 0.0, sv[:, 0] / sv[:, -1], np.inf)


def _fail(arm, T, q_prev, k, reason, message, extra):
    """Raise ``UnreachableError``; the closest pose is the last one reached continuously."""
    pose = fk(arm, q_prev)
    pos, rot = pose_error(pose, T)
    details = {'waypoint': int(k), 'position_error': pos, 'orientation_error': rot,
               'closest_q': q_prev, 'closest_pose': pose, 'message': message}
    details.update(extra)
    raise UnreachableError(message, reason=reason, details=details)
