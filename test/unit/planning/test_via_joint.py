"""The joint move through one via pose: the Jacobians and trajectories report's via-point law."""

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import goal_relative_to_start, pose_error
from mover6_control.motion.timing.time_laws import via_fraction, via_point_polynomial
from mover6_control.planning.planner_core import PlannerSettings
from mover6_control.planning.via_joint import (plan_via_joint_move, plan_via_path_goal,
                                               sample_curve, TAU_VIA, via_joint_curve)
import numpy as np
import pytest

ARM = mover6()
HOME = np.zeros(6)
# The README's example: via (0.32, 0, 0.38), goal (0.30, 0.08, 0.34), home orientation.
T_VIA = goal_relative_to_start(fk(ARM, HOME), 0.32, 0.0, 0.38, 0.0, 0.0, 0.0)
T_GOAL = goal_relative_to_start(fk(ARM, HOME), 0.30, 0.08, 0.34, 0.0, 0.0, 0.0)


def test_each_joint_follows_the_reports_law_with_its_via_fraction():
    q_start = np.array([0.1, -0.2, 0.3, 0.0, 0.4, -0.1])
    q_via = np.array([0.3, 0.1, 0.2, 0.2, 0.5, -0.1])
    q_goal = np.array([0.5, 0.2, -0.1, 0.3, 0.6, -0.1])   # joint 6 ends where it starts
    tau = np.linspace(0.0, 1.0, 101)
    q = via_joint_curve(q_start, q_via, q_goal, tau)
    for j in range(5):
        law = via_point_polynomial(via_fraction(q_start[j], q_via[j], q_goal[j]), TAU_VIA)
        np.testing.assert_allclose(q[:, j], q_start[j] + (q_goal[j] - q_start[j]) * law(tau),
                                   atol=1e-12)
    np.testing.assert_allclose(q[:, 5], -0.1, atol=1e-12)   # no via fraction: stays put
    np.testing.assert_allclose(q[0], q_start, atol=1e-12)
    np.testing.assert_allclose(q[50], q_via, atol=1e-12)    # at tau_via = 0.5
    np.testing.assert_allclose(q[-1], q_goal, atol=1e-12)


def test_the_reports_example_law():
    # The Jacobians and trajectories report: 27.13 tau^6 - 75.40 tau^5 + 66.40 tau^4 - 17.13 tau^3
    law = via_point_polynomial(via_fraction(83.14, 90.0, 173.37))
    np.testing.assert_allclose(law.coefficients[3:], [-17.13, 66.40, -75.40, 27.13], atol=0.01)


def test_plan_from_home_passes_the_via_and_ends_at_the_goal():
    settings = PlannerSettings()
    plan = plan_via_joint_move(ARM, HOME, T_VIA, T_GOAL, settings)
    assert plan.motion == 'joint'
    np.testing.assert_allclose(plan.q[0], HOME)
    via_errors = [pose_error(fk(ARM, q), T_VIA) for q in plan.q]
    assert min(p for p, _ in via_errors) < 1e-6          # the via configuration is a row
    assert min(r for _, r in via_errors) < 1e-6
    pos, rot = pose_error(fk(ARM, plan.q[-1]), T_GOAL)
    assert pos < 1e-6 and rot < 1e-6
    assert plan.n_waypoints >= settings.n_waypoints
    assert np.abs(np.diff(plan.q, axis=0)).max() <= settings.max_joint_step / 2 + 1e-9
    assert all(ARM.within_limits(q) for q in plan.q)


def test_the_goal_already_reached_is_a_two_row_hold():
    T = fk(ARM, HOME)
    plan = plan_via_joint_move(ARM, HOME, T, T)
    assert plan.q.shape == (2, 6) and np.allclose(plan.q, 0.0)


def test_a_via_out_of_reach_is_refused_for_what_it_is():
    T_far = T_VIA.copy()
    T_far[:3, 3] = (1.0, 0.0, 0.4)
    with pytest.raises(UnreachableError) as err:
        plan_via_joint_move(ARM, HOME, T_far, T_GOAL)
    assert err.value.reason == 'out_of_reach' and 'via pose 0' in str(err.value)


def test_exactly_one_via_pose():
    with pytest.raises(InvalidInputError, match='exactly one via pose'):
        plan_via_path_goal(ARM, HOME, np.stack([T_VIA, T_VIA]), T_GOAL)
    with pytest.raises(InvalidInputError, match='exactly one via pose'):
        plan_via_path_goal(ARM, HOME, np.zeros((0, 4, 4)), T_GOAL)


def test_a_polynomial_that_overshoots_out_of_the_limits_is_refused():
    # A via close to the start makes the degree-6 law swing back first (the report's example
    # dips below 0): from a joint at its lower limit that is outside the limits.
    q_start = np.zeros(6)
    q_start[1] = ARM.lower[1]
    q_via, q_goal = q_start.copy(), q_start.copy()
    q_via[1] += 0.05
    q_goal[1] += 1.0
    assert via_joint_curve(q_start, q_via, q_goal, [0.1])[0, 1] < ARM.lower[1]
    with pytest.raises(UnreachableError) as err:
        sample_curve(ARM, q_start, q_via, q_goal, PlannerSettings())
    assert err.value.reason == 'joint_limits'


def test_a_goal_in_the_table_is_refused_for_the_collision():
    """Issue 24 (4): the via joint move is checked for collisions as every other goal."""
    T_table = fk(ARM, HOME)
    down = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])   # flange down
    T_table[:3, :3] = down @ T_table[:3, :3]
    T_table[:3, 3] = (0.25, 0.0, -0.05)
    with pytest.raises(UnreachableError) as err:
        plan_via_path_goal(ARM, HOME, T_VIA[None], T_table)
    assert err.value.reason == 'collision'
    assert 'link6 tool is 150 mm into the table margin' in str(err.value)
