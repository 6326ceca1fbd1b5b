"""
A joint move through one via pose: the Jacobians and trajectories report's via-point polynomial.

The report's via-point law is the degree-6 polynomial ``s(tau)`` with ``s(0) = 0``,
``s(1) = 1``, zero rate and acceleration at both ends and ``s(tau_via) = S``
(``time_laws.via_point_polynomial``), ``S`` the via fraction of a joint
(``time_laws.via_fraction``). Each joint ``j`` follows
``q_j(tau) = q_start_j + (q_goal_j - q_start_j) s_j(tau)`` with its own ``S_j``, so the arm is
at the via configuration at ``tau_via`` exactly. Written as a sum of two laws of the library,

    q(tau) = q_start + (q_goal - q_start) b_goal(tau) + (q_via - q_start) b_via(tau),
    b_goal = via_point_polynomial(0), b_via = via_point_polynomial(1) - b_goal,

the same curve is defined for a joint whose goal equals its start (``S`` undefined there).

One timing model: the planner sends the polynomial's curve, densely sampled (``sample_curve``:
the via configuration one of the rows), as the demand's waypoints, and the controller times them
with its law (``profile``, or the demand's own; ``continuous`` goes through them without
stopping), as it times every other shape; the planner announces that same timing
(``planners.predicted_duration``). The alternative, a controller law that plays the
polynomial's own clock from a [via, goal] demand, would be a second timing model: a law valid
for two-row demands only, and a duration the planner would have to predict apart.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mover6_control.errors import UnreachableError
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.rotations import pose_error
from mover6_control.motion.timing.time_laws import via_point_polynomial
from mover6_control.planning.planner_core import (check_goal, check_goal_collision,
                                                  check_path_shape, check_plan_collision,
                                                  closest_solution, JointPlan, make_checker,
                                                  PlannerSettings, polyline_length, travel_time)
from mover6_control.values import ToolPose
import numpy as np

if TYPE_CHECKING:
    from mover6_control.collision.checker import CollisionChecker
    from mover6_control.kinematics.arm import ArmModel

TAU_VIA = 0.5          # the report's example: the via point at half the move's time
FINE = 400             # curve samples per half, to check the limits and measure the curve


def via_joint_curve(q_start: np.ndarray, q_via: np.ndarray, q_goal: np.ndarray,
                    tau: np.ndarray, tau_via: float = TAU_VIA) -> np.ndarray:
    """
    Return ``q(tau)`` (len(tau), n) [rad] of the via-point polynomial (module docstring).

    Per joint with ``q_goal != q_start`` this is the report's law with
    ``S = via_fraction(q_start, q_via, q_goal)``.
    """
    b_goal = via_point_polynomial(0.0, tau_via)
    b_via = via_point_polynomial(1.0, tau_via)
    tau = np.asarray(tau, dtype=float)
    s_goal = b_goal(tau)[:, None]
    s_via = b_via(tau)[:, None] - s_goal
    q_start = np.asarray(q_start, dtype=float)
    return (q_start + s_goal * (np.asarray(q_goal) - q_start)
            + s_via * (np.asarray(q_via) - q_start))


def _arc_samples(q_fine: np.ndarray, n: int) -> np.ndarray:
    """Return ``n`` rows of the fine curve (k, 6) evenly spaced along its joint-space length."""
    steps = np.abs(np.diff(q_fine, axis=0)).max(axis=1)
    length = np.concatenate([[0.0], np.cumsum(steps)])
    if length[-1] <= 0.0:
        return q_fine[[0, -1]]
    targets = np.linspace(0.0, length[-1], n)
    return np.stack([np.interp(targets, length, q_fine[:, j]) for j in range(q_fine.shape[1])],
                    axis=1)


def sample_curve(arm: ArmModel, q_start: np.ndarray, q_via: np.ndarray, q_goal: np.ndarray,
                 settings: PlannerSettings, tau_via: float = TAU_VIA) -> np.ndarray:
    """
    Return the waypoints (m, 6) [rad] of the via-point polynomial from ``q_start``.

    Each half (start to via, via to goal) is sampled evenly along its joint-space length, no
    step above half ``settings.max_joint_step`` and at least ``settings.n_waypoints`` rows in
    all; the via configuration is a row exactly, the first row is ``q_start``. Raises
    ``UnreachableError`` (``joint_limits``) when the polynomial leaves the joint limits on the
    way (it overshoots when the via is far from the straight line's pace).
    """
    halves = [np.linspace(0.0, tau_via, FINE), np.linspace(tau_via, 1.0, FINE)]
    fine = [via_joint_curve(q_start, q_via, q_goal, tau, tau_via) for tau in halves]
    for part in fine:
        outside = [k for k, q in enumerate(part) if not arm.within_limits(q)]
        if outside:
            q_bad = part[outside[0]]
            raise UnreachableError(
                'the via-point polynomial leaves the joint limits on the way: '
                + '; '.join(arm.limit_violations(q_bad)),
                reason='joint_limits',
                details={'waypoint': -1, 'closest_q': q_bad, 'closest_pose': fk(arm, q_bad)})
    lengths = [np.abs(np.diff(part, axis=0)).max(axis=1).sum() for part in fine]
    rows = []
    for part, length in zip(fine, lengths):
        share = length / max(sum(lengths), 1e-12)
        n = max(2, int(np.ceil(2.0 * length / settings.max_joint_step)) + 1,
                int(np.ceil(share * settings.n_waypoints)) + 1)
        rows.append(_arc_samples(part, n))
    q = np.vstack([rows[0], rows[1][1:]])
    q[0] = q_start
    return q


def plan_via_joint_move(arm: ArmModel, q_current: np.ndarray, T_via: np.ndarray,
                        T_goal: np.ndarray, settings: PlannerSettings = PlannerSettings(),
                        checker: CollisionChecker | None = None) -> JointPlan:
    """
    Plan a joint-space move from ``q_current`` through the via pose ``T_via`` to ``T_goal``.

    The via configuration is the IK solution nearest ``q_current``, the goal's the one nearest
    the via's; the curve is the via-point polynomial (module docstring), sampled by
    ``sample_curve``. Refusals as a joint move's (``check_goal`` with a singular pose accepted,
    then joint limits / out of reach), and ``joint_limits`` when the curve leaves the limits.
    The collision check is a pose goal's (``plan_pose_goal``): the goal first, then the whole
    swept curve (``checker``, else one made from ``settings.collision``). Raises
    ``InvalidInputError`` on malformed input.
    """
    q_current = arm.check_q(q_current, 'current joint positions')
    T_via = ToolPose.of(T_via, 'via pose 0')      # ToolPose values (a message's) pass unchecked
    T_goal = ToolPose.of(T_goal, 'goal pose')
    check_goal(arm, T_via, q_current, settings, what='via pose 0', singular_ok=True)
    check_goal(arm, T_goal, q_current, settings, singular_ok=True)
    checker = checker or make_checker(arm, settings)
    check_goal_collision(arm, T_goal, q_current, checker)
    q_via = closest_solution(arm, T_via, q_current, 'via pose 0')
    q_goal = closest_solution(arm, T_goal, q_via, 'goal')
    if np.abs(q_goal - q_current).max() < 1e-9 and np.abs(q_via - q_current).max() < 1e-9:
        q = np.stack([q_current, q_current])
    else:
        q = sample_curve(arm, q_current, q_via, q_goal, settings)
    poses = fk_batch(arm, q)
    pos_err, rot_err = pose_error(poses[-1], T_goal)
    if pos_err > settings.position_tolerance or rot_err > settings.orientation_tolerance:
        raise UnreachableError(   # IK is exact: this guards the arm model, not the goal
            f'the last waypoint misses the goal by {pos_err * 1e3:.2f} mm and {rot_err:.4f} rad',
            reason='out_of_reach', details={'waypoint': len(q) - 1})
    return check_plan_collision(JointPlan(
        motion='joint', q=q, poses=poses, path_length=polyline_length(poses[:, :3, 3]),
        predicted_duration=travel_time(arm, q, settings.velocity_scale),
        final_position_error=pos_err, final_orientation_error=rot_err), checker)


def plan_via_path_goal(arm: ArmModel, q_current: np.ndarray, T_vias: np.ndarray,
                       T_goal: np.ndarray, settings: PlannerSettings = PlannerSettings(),
                       checker: CollisionChecker | None = None) -> JointPlan:
    """
    Plan a ``/path_goal/joint`` goal: exactly one via pose (k = 1, (k, 4, 4)), then the goal.

    Checked as every path goal is (``check_path_shape`` first), collisions included.
    """
    if not isinstance(T_vias, (list, tuple)):
        T_vias = np.asarray(T_vias, dtype=float).reshape(-1, 4, 4)
    check_path_shape('joint', len(T_vias))
    return plan_via_joint_move(arm, q_current, T_vias[0], T_goal, settings, checker)
