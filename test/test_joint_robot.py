"""Joint and Robot: the Mover6 report's classes, eq. 1-2 (synchronised), 16-19 (trapezoid)."""

from hypothesis import given, settings
import hypothesis.strategies as st
from mover6_control.control.joint import Joint
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


def test_measurement_and_demand_remember_the_start():
    robot = Robot.from_arm(mover6()).with_measurement([0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
                                                      [1, 2, 3, 4, 5, 6])
    robot = robot.with_demand([0.0, -0.2, 0.3, 1.0, 0.5, 0.0])
    np.testing.assert_allclose(robot.q_initial, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_allclose(robot.qd, [1, 2, 3, 4, 5, 6])
    assert [j.direction for j in robot.joints] == [-1.0, -1.0, 0.0, 1.0, 0.0, -1.0]


def test_demand_outside_limits_names_the_joint():
    robot = Robot.from_arm(mover6())
    with pytest.raises(InvalidInputError, match='joint3'):
        robot.with_demand([0, 0, 2.0, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='non-finite'):
        robot.with_demand([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='shape'):
        robot.with_demand([0, 0, 0])


def test_joint_rejects_bad_values():
    with pytest.raises(InvalidInputError):
        Joint('j', 1.0, -1.0, 1.0)
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 0.0)
    with pytest.raises(InvalidInputError):
        Joint('j', -1.0, 1.0, 1.0, q=float('inf'))


def test_synchronised_seed_numbers():
    # the Mover6 report: lambda = 2 rad/s; joint 2 travels furthest (0.8 rad) so t_max = 0.4 s (eq.
    # 1).
    robot = Robot.from_arm(mover6()).with_demand([0.4, -0.8, 0.2, 0.0, 0.1, 0.0])
    assert robot.max_time(2.0) == pytest.approx(0.4)
    np.testing.assert_allclose(robot.synchronised_velocities(2.0),
                               [1.0, -2.0, 0.5, 0.0, 0.25, 0.0])     # eq. 2


@settings(max_examples=40, deadline=None)
@given(st.lists(angle, min_size=6, max_size=6), st.lists(angle, min_size=6, max_size=6),
       st.floats(0.1, 3.0))
def test_synchronised_all_arrive_together(q0, q1, lam):
    robot = Robot.from_arm(mover6()).with_measurement(q0).with_demand(q1)
    t_max = robot.max_time(lam)
    v = robot.synchronised_velocities(lam)
    assert np.max(np.abs(v)) == pytest.approx(lam if t_max > 0 else 0.0)
    np.testing.assert_allclose(np.asarray(q0) + v * t_max, q1, atol=1e-12)


def test_trapezoid_seed_defaults_eq16_to_19():
    # the Mover6 report: t_max = 1 s, t_blend = t_max / 4; a move of 0.3 rad gives V_max = 0.4
    # rad/s.
    joint = Joint('joint1', -1.571, 1.571, 1.0, q=0.2).with_demand(-0.1)
    t_max, t_blend = 1.0, 0.25
    v_max = 0.3 / (t_max - t_blend)                                        # eq. 16
    assert joint.trapezoidal_velocity(0.5, t_max) == pytest.approx(-v_max)  # plateau, eq. 18
    assert joint.trapezoidal_velocity(0.125, t_max) == pytest.approx(-v_max / 2)
    assert joint.trapezoidal_velocity(0.875, t_max) == pytest.approx(-v_max / 2)
    assert joint.trapezoidal_velocity(1.0, t_max) == 0.0
    assert joint.trapezoidal_velocity(-0.1, t_max) == 0.0
    dt = 1e-4
    ts = np.arange(0.0, t_max, dt) + dt / 2
    s = sum(joint.trapezoidal_velocity(t, t_max, t_blend) for t in ts) * dt   # eq. 19
    assert s == pytest.approx(-0.3, abs=1e-7)


def test_trapezoid_rejects_a_blend_too_long():
    joint = Joint('joint1', -1.0, 1.0, 1.0).with_demand(0.5)
    with pytest.raises(InvalidInputError, match='t_blend'):
        joint.trapezoidal_velocity(0.1, 1.0, 0.5)


def test_robot_trapezoid_is_per_joint():
    robot = Robot.from_arm(mover6()).with_demand([0.3, -0.6, 0, 0, 0, 0.15])
    np.testing.assert_allclose(robot.trapezoidal_velocities(0.5, 1.0),
                               [0.4, -0.8, 0, 0, 0, 0.2])
