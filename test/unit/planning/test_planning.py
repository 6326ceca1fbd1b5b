"""Planning from the current configuration to a goal (ROS-free): shapes, singular starts."""

from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.rotations import pose_error, pose_from_xyzabc
from mover6_control.motion.metrics import max_deviation_from_polyline
from mover6_control.planning.planner_core import plan_path_goal, plan_pose_goal, PlannerSettings
from mover6_control.tools.goal_convention import pose_from_goal
import numpy as np
import pytest

ARM = mover6()
HOME = np.zeros(6)
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
SETTINGS = PlannerSettings()


def check_plan(plan, q_start, T_goal, settings=SETTINGS):
    """Assert the invariants every plan keeps."""
    Q = plan.q
    assert Q.shape[1] == 6 and Q.shape[0] >= 2
    assert np.allclose(Q[0], q_start)
    assert all(ARM.within_limits(q) for q in Q)
    assert np.abs(np.diff(Q, axis=0)).max() <= settings.max_joint_step + 1e-12
    pos, rot = pose_error(fk(ARM, Q[-1]), T_goal)
    assert pos <= settings.position_tolerance and rot <= settings.orientation_tolerance


def test_linear_from_singular_home_inserts_a_wrist_turn_that_stays_on_the_line():
    """Home (q5 = 0) is singular: the plan turns the wrist in place first, then follows."""
    plan = plan_pose_goal(ARM, HOME, GOAL, 'linear')
    check_plan(plan, HOME, GOAL)
    assert plan.n_waypoints > SETTINGS.n_waypoints   # the wrist turn was inserted
    # FK of a fine joint-space interpolation of the waypoints stays on the straight line.
    fine = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a)
                           for a, b in zip(plan.q[:-1], plan.q[1:])])
    line = np.stack([fk(ARM, HOME)[:3, 3], GOAL[:3, 3]])
    assert max_deviation_from_polyline(fk_batch(ARM, fine)[:, :3, 3], line) < 1e-3


@pytest.mark.parametrize('n', [3, 5, 50])
def test_wrist_turn_is_made_in_place_for_any_sampling(n):
    """However coarse the path, the turn out of the singular home keeps the tool still."""
    settings = PlannerSettings(n_waypoints=n)
    plan = plan_pose_goal(ARM, HOME, GOAL, 'linear', settings)
    check_plan(plan, HOME, GOAL, settings)
    turn = plan.q[:plan.n_waypoints - n + 1]
    for T in fk_batch(ARM, turn):
        pos, rot = pose_error(T, fk(ARM, HOME))
        assert pos < 1e-9 and rot < 1e-9


def test_linear_from_a_regular_pose_needs_no_wrist_turn():
    """Away from singularities the plan is exactly the sampled path."""
    q0 = plan_pose_goal(ARM, HOME, GOAL, 'linear').q[-1]
    goal = pose_from_xyzabc(0.30, -0.05, 0.33, 0.0, np.pi / 2, 0.0)
    plan = plan_pose_goal(ARM, q0, goal, 'linear')
    check_plan(plan, q0, goal)
    assert plan.n_waypoints == SETTINGS.n_waypoints


@pytest.mark.parametrize('motion', ['parabolic', 'joint'])
def test_other_pose_motions_reach_the_goal(motion):
    """Parabolic and joint moves end at the goal within tolerance."""
    q0 = plan_pose_goal(ARM, HOME, GOAL, 'linear').q[-1]
    goal = pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0)
    plan = plan_pose_goal(ARM, q0, goal, motion)
    check_plan(plan, q0, goal)
    if motion == 'parabolic':
        mid = plan.poses[len(plan.poses) // 2][:3, 3]
        straight_mid = (fk(ARM, q0)[:3, 3] + goal[:3, 3]) / 2
        assert mid[2] > straight_mid[2] + 0.5 * SETTINGS.peak_height


def test_spline_and_arc_through_via_poses():
    """Path goals pass through their via pose."""
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    goal = pose_from_xyzabc(0.28, 0.10, 0.36, 0.0, np.pi / 2, 0.0)
    for motion in ('spline', 'arc'):
        plan = plan_path_goal(ARM, HOME, via[None], goal, motion)
        check_plan(plan, HOME, goal)
        d = np.linalg.norm(fk_batch(ARM, plan.q)[:, :3, 3] - via[:3, 3], axis=1).min()
        assert d < 0.01, f'{motion} passes {d * 1e3:.1f} mm from the via pose'


def test_goal_at_the_current_pose_is_a_hold():
    """A goal equal to the current pose plans a two-row hold, not an error."""
    plan = plan_pose_goal(ARM, HOME, fk(ARM, HOME), 'linear')
    assert plan.q.shape == (2, 6) and np.allclose(plan.q, HOME)


def test_unreachable_goal_and_bad_input_raise_with_reasons():
    """Refusals carry a reason; bad input is an InvalidInputError."""
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, HOME, pose_from_xyzabc(0.9, 0.0, 0.4, 0.0, np.pi / 2, 0.0))
    assert err.value.reason == 'out_of_reach'
    with pytest.raises(InvalidInputError):
        plan_pose_goal(ARM, HOME, GOAL, 'zigzag')
    with pytest.raises(InvalidInputError):
        plan_pose_goal(ARM, [0.0, np.nan, 0, 0, 0, 0], GOAL)
    with pytest.raises(InvalidInputError):
        plan_path_goal(ARM, HOME, np.stack([GOAL, GOAL]), GOAL, 'arc')
    with pytest.raises(InvalidInputError):
        PlannerSettings(n_waypoints=1)


def test_a_path_refusal_says_a_joint_move_gets_to_the_goal():
    """From the report's IK example, the README's next line is refused on the way; joint: fine."""
    q_ik = plan_pose_goal(ARM, HOME, pose_from_goal(ARM, 0.1, 0.1, 0.2, 0.0, np.pi / 2, 0.0),
                          'linear').q[-1]
    goal = pose_from_goal(ARM, 0.30, 0.05, 0.36, 0.0, 0.0, 0.0)
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, q_ik, goal, 'linear')
    assert err.value.reason in ('discontinuity', 'joint_limits')
    assert 'the goal itself is reachable inside the limits: a joint move' in str(err.value)
    plan = plan_pose_goal(ARM, q_ik, goal, 'joint')
    position, _ = pose_error(fk(ARM, plan.q[-1]), goal)
    assert position < 1e-6
