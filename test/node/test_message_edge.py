"""
The edge: each message a node takes becomes a checked value once, or is refused with a code.

``nodes/messages/conversions.py`` and ``demand_messages.py`` make ``values.ToolPose``,
``values.JogRequest`` and ``values.JointDemand``; the planning below takes a pose goal without
checking it again (the checks are counted on one goal's way to its joint waypoints).
"""

import math

from control_msgs.msg import JointJog
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control import values
from mover6_control.errors import error_code, InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.nodes.messages import cdr, conversions, demand_messages
from mover6_control.planning.planner_core import plan_path_goal, plan_pose_goal
import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

ARM = mover6()
Q_GOAL = np.array([0.3, 0.2, 0.1, 0.2, 0.3, 0.1])
NAMES = list(ARM.joint_names)


def code_of(make):
    """Return the code ``make()`` is refused with (it must be refused)."""
    with pytest.raises(InvalidInputError) as refused:
        make()
    return error_code(refused.value)


def pose_goal(frame='base_link', **changes):
    """Return a PoseStamped of a reachable goal, with fields of its pose changed."""
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose = conversions.matrix_to_pose(fk(ARM, Q_GOAL))
    for path, value in changes.items():
        part, field = path.split('__')
        setattr(getattr(msg.pose, part), field, value)
    return msg


@pytest.mark.parametrize('msg, code', [
    (pose_goal(position__x=math.nan), 'non_finite'),
    (pose_goal(orientation__w=math.inf), 'non_finite'),
    (pose_goal(orientation__x=0.0, orientation__y=0.0, orientation__z=0.0, orientation__w=0.0),
     'bad_quaternion'),
    (pose_goal(orientation__w=3.0), 'bad_quaternion'),
    (pose_goal(frame='world'), 'wrong_frame'),
])
def test_a_bad_pose_goal_is_refused_with_its_code(msg, code):
    assert code_of(lambda: conversions.pose_goal_from_msg(msg, 'base_link')) == code


def test_a_path_goal_is_refused_when_empty_or_when_one_pose_is_bad():
    msg = PoseArray()
    msg.header.frame_id = 'base_link'
    assert code_of(lambda: conversions.path_goal_from_msg(msg)) == 'empty'
    msg.poses = [pose_goal().pose, pose_goal(position__z=math.nan).pose]
    assert code_of(lambda: conversions.path_goal_from_msg(msg)) == 'non_finite'


def count_transform_checks(monkeypatch):
    """Count the calls of the one transform check (``values._checked_transform``)."""
    calls = []
    check = values._checked_transform
    monkeypatch.setattr(values, '_checked_transform',
                        lambda *args: calls.append(args[1]) or check(*args))
    return calls


@pytest.mark.parametrize('motion', ['linear', 'joint'])
def test_a_pose_goal_is_checked_at_the_edge_and_not_again_on_its_way(monkeypatch, motion):
    goal = conversions.pose_goal_from_msg(pose_goal())
    assert isinstance(goal, values.ToolPose)
    calls = count_transform_checks(monkeypatch)
    plan = plan_pose_goal(ARM, np.zeros(6), goal, motion)
    demand = demand_messages.make_demands(plan.q)
    assert np.abs(demand_messages.demands_from_msg(demand)[-1] - Q_GOAL).max() < 1e-3
    assert calls == []


def test_a_path_goal_is_checked_at_the_edge_and_not_again_on_its_way(monkeypatch):
    via = conversions.matrix_to_pose(fk(ARM, 0.5 * Q_GOAL))
    msg = PoseArray()
    msg.header.frame_id = 'base_link'
    msg.poses = [via, pose_goal().pose]
    poses = conversions.path_goal_from_msg(msg)
    calls = count_transform_checks(monkeypatch)
    plan_path_goal(ARM, np.zeros(6), poses[:-1], poses[-1], 'spline')
    assert calls == []


def test_a_raw_goal_handed_to_the_planner_is_still_checked():
    T = fk(ARM, Q_GOAL)
    T[0, 0] = 2.0
    assert code_of(lambda: plan_pose_goal(ARM, np.zeros(6), T, 'linear')) == 'not_a_transform'


def jog(names, velocities, displacements=()):
    msg = JointJog()
    msg.joint_names = list(names)
    msg.velocities = list(velocities)
    msg.displacements = list(displacements)
    return msg


@pytest.mark.parametrize('msg, code', [
    (jog(['joint1'], [0.1], [0.1]), 'displacements'),
    (jog([], []), 'empty'),
    (jog(['joint1', 'joint2'], [0.1]), 'length'),
    (jog(['joint1', 'joint1'], [0.1, 0.1]), 'names'),
    (jog(['joint1'], [math.nan]), 'non_finite'),
])
def test_a_bad_joint_jog_is_refused_with_its_code(msg, code):
    assert code_of(lambda: conversions.joint_jog_from_msg(msg)) == code
    if code != 'displacements':        # the simulator's raw input reads no displacements
        raw = serialize_message(msg)
        assert code_of(lambda: conversions.joint_jog_from_raw(raw, cdr.JointJogReader())) == code


def test_a_joint_jog_becomes_one_checked_request():
    jog_request = conversions.joint_jog_from_msg(jog(['joint2', 'joint1'], [0.1, -0.2]))
    assert jog_request == values.JogRequest(('joint2', 'joint1'), (0.1, -0.2))
    raw = serialize_message(jog(['joint2', 'joint1'], [0.1, -0.2]))
    assert conversions.joint_jog_from_raw(raw, cdr.JointJogReader()) == jog_request


def demands(data, dims=None):
    msg = Float32MultiArray()
    msg.data = [float(v) for v in data]
    if dims is not None:
        msg.layout.dim = demand_messages.make_demands(np.zeros(dims)).layout.dim
    return msg


@pytest.mark.parametrize('msg, code', [
    (demands([]), 'empty'),
    (demands([0.0] * 7), 'bad_shape'),
    (demands([0.0] * 6, dims=(2, 6)), 'bad_shape'),
    (demands([0.0] * 5 + [math.nan]), 'non_finite'),
])
def test_a_bad_demand_is_refused_with_its_code(msg, code):
    assert code_of(lambda: demand_messages.demand_from_msg(msg)) == code


def test_bad_joint_states_are_refused_with_their_code():
    msg = JointState(name=NAMES, position=[0.0] * 5)
    assert code_of(lambda: conversions.joint_state_from_msg(msg, NAMES)) == 'length'
    msg = JointState(name=NAMES, position=[0.0] * 5 + [math.inf])
    assert code_of(lambda: conversions.joint_state_from_msg(msg, NAMES)) == 'non_finite'
