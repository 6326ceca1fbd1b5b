"""Joint and Robot: the Mover6 report's classes, eq. 1-2 (synchronised), 16-19 (trapezoid)."""

from hypothesis import given, settings
import hypothesis.strategies as st
from mover6_control.control.commands import common_scale
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.joint import Joint
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.control.robot import Robot
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest

angle = st.floats(-1.5, 1.5, allow_nan=False)


def test_from_arm_keeps_names_and_limits():
    arm = mover6('hardware')
    robot = Robot.from_arm(arm)
    assert robot.joint_names == arm.joint_names
    np.testing.assert_allclose(robot.lower, arm.lower)
    np.testing.assert_allclose(robot.upper, arm.upper)
    np.testing.assert_allclose(robot.velocity_limits, arm.velocity_limits)
    np.testing.assert_allclose(robot.q, np.zeros(6))


def report_plan(q0, q1, **law):
    """Return the controller's plan from q0 to q1 (one waypoint), limits too wide to stretch."""
    q0 = np.asarray(q0, dtype=float)
    return plan_motion(LawConfig(**law), q0, np.asarray(q1, dtype=float)[None],
                       np.full(q0.shape, 10.0))


def test_measurement_and_demand_remember_the_start():
    robot = Robot.from_arm(mover6())
    robot.measure(0.0, robot.joint_names, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], [1, 2, 3, 4, 5, 6])
    robot.give(report_plan(robot.q, [0.0, -0.2, 0.3, 1.0, 0.5, 0.0], profile='synchronised'),
               0.0)
    np.testing.assert_allclose(robot.q_initial, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_allclose(robot.qd, [1, 2, 3, 4, 5, 6])
    assert [j.direction for j in robot.joints] == [-1.0, -1.0, 0.0, 1.0, 0.0, -1.0]


def test_demand_outside_limits_names_the_joint():
    core = ControllerCore(mover6())          # the check every demand passes
    with pytest.raises(InvalidInputError, match='joint3'):
        core.check_demand([0, 0, 2.0, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='non-finite'):
        core.check_demand([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='shape'):
        core.check_demand([[0, 0, 0]])


def test_joint_rejects_bad_values():
    with pytest.raises(InvalidInputError):
        Joint('j', 1.0, -1.0, 1.0)
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 0.0)
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 1.0, q=float('inf'))


def test_synchronised_mover6_report_numbers():
    # the Mover6 report: lambda = 2 rad/s; joint 2 travels furthest (0.8 rad) so t_max = 0.4 s (eq.
    # 1).
    plan = report_plan(np.zeros(6), [0.4, -0.8, 0.2, 0.0, 0.1, 0.0], profile='synchronised',
                       lambda_max=2.0)
    assert plan.duration == pytest.approx(0.4)
    np.testing.assert_allclose(plan.sample(0.2)[1],
                               [1.0, -2.0, 0.5, 0.0, 0.25, 0.0])     # eq. 2


@settings(max_examples=40, deadline=None)
@given(st.lists(angle, min_size=6, max_size=6), st.lists(angle, min_size=6, max_size=6),
       st.floats(0.1, 3.0))
def test_synchronised_all_arrive_together(q0, q1, lam):
    plan = report_plan(q0, q1, profile='synchronised', lambda_max=lam)
    t_max = plan.duration
    v = plan.sample(0.5 * t_max)[1]
    assert np.max(np.abs(v)) == pytest.approx(lam if t_max > 0 else 0.0)
    np.testing.assert_allclose(np.asarray(q0) + v * t_max, q1, atol=1e-12)


def test_trapezoid_mover6_report_defaults_eq16_to_19():
    # the Mover6 report: t_max = 1 s, t_blend = t_max / 4; a move of 0.3 rad gives V_max = 0.4
    # rad/s.
    plan = report_plan([0.2], [-0.1], profile='trapezoidal', t_max=1.0)   # t_blend default
    t_max, t_blend = 1.0, 0.25
    v_max = 0.3 / (t_max - t_blend)                                        # eq. 16

    def velocity(t):
        return float(plan.sample(t)[1][0])
    assert velocity(0.5) == pytest.approx(-v_max)                          # plateau, eq. 18
    assert velocity(0.125) == pytest.approx(-v_max / 2)
    assert velocity(0.875) == pytest.approx(-v_max / 2)
    assert velocity(1.0) == 0.0
    assert velocity(-0.1) == 0.0
    dt = 1e-4
    ts = np.arange(0.0, t_max, dt) + dt / 2
    s = sum(velocity(t) for t in ts) * dt                                  # eq. 19
    assert s == pytest.approx(-0.3, abs=1e-7)


def test_trapezoid_rejects_a_blend_too_long():
    with pytest.raises(InvalidInputError, match='t_blend'):
        LawConfig(profile='trapezoidal', t_max=1.0, t_blend=0.5)


def test_robot_trapezoid_is_per_joint():
    plan = report_plan(np.zeros(6), [0.3, -0.6, 0, 0, 0, 0.15], profile='trapezoidal',
                       t_max=1.0)
    np.testing.assert_allclose(plan.sample(0.5)[1], [0.4, -0.8, 0, 0, 0, 0.2])


def test_measure_maps_by_name_in_any_order():
    robot = Robot.from_arm(mover6())
    names = list(reversed(robot.joint_names))
    robot.measure(1.5, names, [6, 5, 4, 3, 2, 1], [0.6, 0.5, 0.4, 0.3, 0.2, 0.1])
    np.testing.assert_allclose(robot.q, [1, 2, 3, 4, 5, 6])
    np.testing.assert_allclose(robot.qd, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    assert robot.joint('joint2').q == 2.0 and robot.joint('joint2').qd == pytest.approx(0.2)
    assert robot.t_states == 1.5 and robot.invalid_reason is None and robot.measured
    robot.measure(2.0, robot.joint_names, [0.0] * 6, [])          # no velocities: zero
    np.testing.assert_allclose(robot.qd, np.zeros(6))


@pytest.mark.parametrize('names, match', [
    (['joint1', 'joint2', 'joint3', 'joint4', 'joint5'], r"lacks joints \['joint6'\]"),
    (['joint1', 'gripper', 'joint3', 'joint4', 'joint5', 'joint6'],
     r"lacks joints \['joint2'\]"),
    (['joint1', 'joint2', 'joint3', 'joint4', 'joint5', 'joint5'], r"repeats joints \['joint5'\]"),
])
def test_measure_refuses_missing_and_repeated_names(names, match):
    robot = Robot.from_arm(mover6())
    robot.measure(0.0, robot.joint_names, np.full(6, 0.1))
    with pytest.raises(InvalidInputError, match=match):
        robot.measure(1.0, names, np.zeros(len(names)))
    assert robot.invalid_reason is not None and 'joint_states' in robot.invalid_reason
    assert robot.states_problem(1.0, 0.25).startswith('invalid /joint_states')
    np.testing.assert_allclose(robot.q, np.full(6, 0.1))          # the last valid states kept
    robot.measure(1.1, robot.joint_names, np.zeros(6))
    assert robot.invalid_reason is None and robot.states_problem(1.1, 0.25) is None
    assert 'stale' in robot.states_problem(2.0, 0.25)


def test_measure_ignores_joints_it_does_not_drive():
    """A /joint_states with a gripper joint too (joint_state_broadcaster sends all) is valid."""
    robot = Robot.from_arm(mover6())
    names = ['gripper'] + list(reversed(robot.joint_names))
    robot.measure(1.0, names, [9, 6, 5, 4, 3, 2, 1], [9, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1])
    np.testing.assert_allclose(robot.q, [1, 2, 3, 4, 5, 6])
    np.testing.assert_allclose(robot.qd, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    assert robot.invalid_reason is None and robot.states_problem(1.0, 0.25) is None


def test_measure_refuses_non_finite_and_mismatched_lengths():
    robot = Robot.from_arm(mover6())
    with pytest.raises(InvalidInputError, match='non-finite'):
        robot.measure(0.0, robot.joint_names, [0, 0, np.nan, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='6 names but 5 positions'):
        robot.measure(0.0, robot.joint_names, np.zeros(5))
    with pytest.raises(InvalidInputError, match='6 names but 2 velocities'):
        robot.measure(0.0, robot.joint_names, np.zeros(6), [0.0, 0.0])
    assert not robot.measured


def test_joint_carries_limits_tolerance_and_encoder_tick():
    arm = mover6()
    robot = Robot.from_arm(arm, goal_tolerance=0.001, acceleration_limit=2.0,
                           encoder_ticks=[1e-5] * 6)
    joint = robot.joint('joint3')
    assert (joint.lower, joint.upper) == (arm.lower[2], arm.upper[2])
    assert joint.velocity_limit == arm.velocity_limits[2]
    assert joint.acceleration_limit == 2.0 and joint.goal_tolerance == 0.001
    assert joint.encoder_tick == 1e-5
    np.testing.assert_allclose(robot.encoder_ticks, np.full(6, 1e-5))
    assert Robot.from_arm(arm).encoder_ticks is None
    with pytest.raises(InvalidInputError, match='no joint "elbow"'):
        robot.joint('elbow')
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 1.0, goal_tolerance=0.0)
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 1.0, encoder_tick=-1e-5)
    joint = Joint('j', -1.0, 1.0, 1.0, q=0.0005, demand=0.0, goal_tolerance=0.001)
    assert joint.distance_to_go == -0.0005 and joint.direction == -1.0


def test_robot_follows_the_plan_it_is_given_and_commands_through_the_law():
    arm = mover6()
    robot = Robot.from_arm(arm)
    robot.measure(0.0, robot.joint_names, np.zeros(6))
    goal = np.array([0.4, -0.8, 0.2, 0.0, 0.1, 0.0])
    plan = plan_motion(LawConfig(profile='synchronised', lambda_max=0.1), robot.q, goal[None],
                       arm.velocity_limits)
    robot.give(plan, 10.0)
    np.testing.assert_allclose(robot.demand, goal)
    np.testing.assert_allclose(robot.q_initial, np.zeros(6))
    # The synchronised law's reference velocity is the Mover6 report's eq. 2 for this robot.
    t = robot.follow(10.1)
    assert t == pytest.approx(0.1)
    qd = robot.command(0.0, arm.velocity_limits)
    np.testing.assert_allclose(qd, goal / (np.max(np.abs(goal)) / 0.1))   # eq. 1-2
    np.testing.assert_allclose(robot.error, robot.reference[0])   # measured at 0
    robot.hold(goal)
    np.testing.assert_allclose(robot.command(2.0, arm.velocity_limits),
                               2.0 * goal / common_scale(2.0 * goal, arm.velocity_limits))
    robot.drop_plan()
    assert robot.plan is None and robot.reference is None
