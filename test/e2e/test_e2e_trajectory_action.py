"""
End to end: the controller's FollowJointTrajectory action, as MoveIt would use it.

The three nodes run as processes; an rclpy ``ActionClient`` in this process sends goals with the
joint names in reversed order and follows feedback and results.
"""

from control_msgs.action import FollowJointTrajectory
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.control.timed_plan import timed_plan, Timing
from mover6_control.kinematics.arm import mover6
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
import rclpy
from rclpy.action import ActionClient
from rclpy.duration import Duration
from ros_testing import ready_client, SETTLE_TOLERANCE, settled_q, Stack, wait_until
from trajectory_msgs.msg import JointTrajectoryPoint

pytestmark = pytest.mark.e2e

ARM = mover6()
Result = FollowJointTrajectory.Result
NAMES = list(ARM.joint_names)
FEEDBACK_STEP = 0.06     # [s] half the feedback period (0.1 s) and a little
LATENCY = 0.03           # [s] a state and a command in flight: two or three control ticks


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start sim_bridge, controller and planner as processes for this module's tests."""
    with Stack(tmp_path_factory.mktemp('fjt_logs')) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return (goal client node, action client) once every node answers."""
    with ready_client(stack, lambda: GoalClient(name='fjt_client'), timeout=30.0) as node:
        action = ActionClient(node, FollowJointTrajectory, '/controller/follow_joint_trajectory')
        assert action.wait_for_server(timeout_sec=20.0), stack.report()
        yield node, action
        action.destroy()


def make_goal(*rows):
    """Return a goal through ``rows`` (each in the arm's joint order), names reversed."""
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = NAMES[::-1]
    for k, q in enumerate(rows):
        point = JointTrajectoryPoint(positions=[float(v) for v in q[::-1]])
        point.time_from_start.sec = k + 1
        goal.trajectory.points.append(point)
    return goal


def send(node, action, goal, feedback=None, timeout=20.0):
    """Send ``goal``; return its accepted goal handle."""
    future = action.send_goal_async(goal, feedback_callback=feedback)
    assert wait_until(future.done, timeout, lambda t: rclpy.spin_once(node, timeout_sec=t))
    handle = future.result()
    assert handle.accepted
    return handle


def result_of(node, handle, timeout=60.0):
    """Wait for and return ``(status, Result)`` of ``handle``."""
    future = handle.get_result_async()
    assert wait_until(future.done, timeout, lambda t: rclpy.spin_once(node, timeout_sec=t))
    response = future.result()
    return response.status, response.result


def test_goal_reached_with_feedback(stack, client):
    """Joint names reversed, two points: SUCCESSFUL, feedback on the way, the arm there."""
    node, action = client
    q_goal = np.array([0.3, -0.2, 0.25, 0.1, 0.3, -0.2])
    feedback = []
    handle = send(node, action, make_goal(q_goal / 2, q_goal),
                  feedback=lambda msg: feedback.append(msg.feedback))
    status, result = result_of(node, handle)
    assert result.error_code == Result.SUCCESSFUL, f'{result.error_string}\n{stack.report()}'
    assert len(feedback) >= 3
    last = feedback[-1]
    assert list(last.joint_names) == NAMES
    assert len(last.desired.positions) == 6 and len(last.actual.positions) == 6
    err = np.array(last.desired.positions) - np.array(last.actual.positions)
    assert np.allclose(err, last.error.positions, atol=1e-9)
    assert np.abs(settled_q(node, stack) - q_goal).max() <= SETTLE_TOLERANCE


def test_out_of_limits_goal_is_invalid(stack, client):
    """A point beyond the joint limits: INVALID_GOAL with the core's reason; nothing moves."""
    node, action = client
    q_before = node.q.copy()
    handle = send(node, action, make_goal(np.array([2.5, 0.0, 0.0, 0.0, 0.0, 0.0])))
    status, result = result_of(node, handle)
    assert result.error_code == Result.INVALID_GOAL, stack.report()
    assert 'joint limits' in result.error_string
    rclpy.spin_once(node, timeout_sec=0.5)
    assert np.abs(node.q - q_before).max() <= SETTLE_TOLERANCE      # held where it was


def test_wrong_joints_are_invalid_joints(stack, client):
    """A goal naming other joints: INVALID_JOINTS with the reason."""
    node, action = client
    goal = make_goal(np.zeros(6))
    goal.trajectory.joint_names = ['a', 'b', 'c', 'd', 'e', 'f']
    status, result = result_of(node, send(node, action, goal))
    assert result.error_code == Result.INVALID_JOINTS
    assert 'joint1' in result.error_string


def test_cancel_stops_the_arm(stack, client):
    """Cancel during a long move: the goal ends canceled, the arm at rest short of the goal."""
    node, action = client
    q_start = node.q.copy()
    q_goal = np.array([-1.2, 0.0, 0.0, 0.0, 0.0, 0.0])
    handle = send(node, action, make_goal(q_goal))
    assert wait_until(lambda: np.abs(node.q - q_start).max() > 0.1, 20.0,
                      lambda t: rclpy.spin_once(node, timeout_sec=t)), stack.report()
    cancel = handle.cancel_goal_async()
    assert wait_until(cancel.done, 10.0, lambda t: rclpy.spin_once(node, timeout_sec=t))
    status, result = result_of(node, handle)
    from action_msgs.msg import GoalStatus
    assert status == GoalStatus.STATUS_CANCELED, result.error_string
    q_stop = node.q.copy()
    assert np.abs(q_stop - q_goal).max() > 0.1          # stopped short of the goal
    for _ in range(20):                                 # and at rest: 20 fresh /joint_states
        node.q = None
        assert wait_until(lambda: node.q is not None, 10.0,
                          lambda t: rclpy.spin_once(node, timeout_sec=t)), stack.report()
        assert np.abs(node.q - q_stop).max() < 0.01


def test_second_goal_preempts_the_first(stack, client):
    """A second goal while the first runs: the first aborted with the reason, the second done."""
    node, action = client
    q_start = node.q.copy()
    first = send(node, action, make_goal(np.array([1.2, 0.0, 0.0, 0.0, 0.0, 0.0])))
    assert wait_until(lambda: np.abs(node.q - q_start).max() > 0.05, 20.0,
                      lambda t: rclpy.spin_once(node, timeout_sec=t)), stack.report()
    q_goal = np.array([0.2, 0.1, 0.0, 0.0, 0.0, 0.0])
    second = send(node, action, make_goal(q_goal))
    from action_msgs.msg import GoalStatus
    status, result = result_of(node, first)
    assert status == GoalStatus.STATUS_ABORTED
    assert 'preempted' in result.error_string
    status, result = result_of(node, second)
    assert result.error_code == Result.SUCCESSFUL, result.error_string
    assert np.abs(settled_q(node, stack) - q_goal).max() <= SETTLE_TOLERANCE


def timed_goal(rows, times):
    """Return a goal through ``rows`` (arm order) at ``times`` [s], names reversed."""
    goal = make_goal(*rows)
    for point, t in zip(goal.trajectory.points, times):
        point.time_from_start = Duration(seconds=t).to_msg()
    return goal


def plan_time(msg):
    """Return ``(stamp - desired.time_from_start)`` of a feedback: when its plan started [s]."""
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    tfs = msg.desired.time_from_start
    return stamp - (tfs.sec + tfs.nanosec * 1e-9)


def test_timed_goal_arrives_at_its_time_from_start(stack, client):
    """Points at 2 s and 4 s (the law alone: about 1 s): the reference is the timed plan."""
    node, action = client
    q_start = node.q.copy()
    Q = np.array([q_start + [0.25, 0.1, 0, 0, 0, 0], q_start + [0.5, 0.2, 0, 0, 0, 0]])
    timing = Timing([2.0, 4.0])
    expected = timed_plan(q_start, Q, timing, ARM.velocity_limits, LawConfig().a_max)
    assert plan_motion(LawConfig(), q_start, Q, ARM.velocity_limits).duration < 2.0
    feedback = []
    handle = send(node, action, timed_goal(Q, timing.times),
                  feedback=lambda msg: feedback.append(msg.feedback))
    status, result = result_of(node, handle)
    assert result.error_code == Result.SUCCESSFUL, f'{result.error_string}\n{stack.report()}'
    assert 'timing' not in result.error_string
    moving = [f for f in feedback if 0.0 < Duration.from_msg(f.desired.time_from_start)
              .nanoseconds * 1e-9 < 4.0]
    assert len(moving) >= 20                       # 10 Hz over the 4 s
    for msg in moving:                             # desired: the timed plan at its time
        t = Duration.from_msg(msg.desired.time_from_start).nanoseconds * 1e-9
        q_ref, qd_ref = expected.sample(t)
        assert np.abs(np.array(msg.desired.positions) - q_ref).max() < 0.002
        assert np.abs(np.array(msg.desired.velocities) - qd_ref).max() < 0.002
    start = plan_time(moving[0])
    # The arm reaches each point at its time, behind by a tick or two of control latency.
    for k, t_point in enumerate(timing.times):
        near = min(feedback, key=lambda f: abs(stamp_s(f) - start - t_point))
        assert abs(stamp_s(near) - start - t_point) <= FEEDBACK_STEP
        speed = np.abs(expected.sample(t_point)[1]).max()
        lag = speed * LATENCY + np.abs(np.array(near.desired.positions) - Q[k]).max()
        assert np.abs(np.array(near.actual.positions) - Q[k]).max() <= lag + 0.002, (
            f'point {k} at {t_point} s: {near.actual.positions}, want {Q[k]}')
    # Not early either: halfway to the first point's time the arm is far from it.
    early = min(feedback, key=lambda f: abs(stamp_s(f) - start - 1.0))
    assert np.abs(np.array(early.actual.positions) - Q[0]).max() > 0.1
    assert np.abs(settled_q(node, stack) - Q[-1]).max() <= SETTLE_TOLERANCE


def test_timed_goal_beyond_the_limits_goes_time_optimal(stack, client):
    """A timing that breaks a_max: time-optimal through the points, the reason in the result."""
    node, action = client
    q_start = node.q.copy()
    Q = np.array([q_start + [-0.3, 0, 0, 0, 0, 0], q_start + [-0.6, 0, 0, 0, 0, 0]])
    law = plan_motion(LawConfig(), q_start, Q, ARM.velocity_limits).duration
    feedback = []
    handle = send(node, action, timed_goal(Q, [0.2, 0.4]),
                  feedback=lambda msg: feedback.append(msg.feedback))
    status, result = result_of(node, handle)
    assert result.error_code == Result.SUCCESSFUL, f'{result.error_string}\n{stack.report()}'
    assert 'timing: time-optimal through the points: the given timing breaks the limits' in (
        result.error_string)
    # The reference took the law's time, not the goal's 0.4 s.
    longest = max(Duration.from_msg(f.desired.time_from_start).nanoseconds * 1e-9
                  for f in feedback)
    assert longest == pytest.approx(law, abs=0.01) and law > 1.0
    assert np.abs(settled_q(node, stack) - Q[-1]).max() <= SETTLE_TOLERANCE


def stamp_s(msg):
    """Return a feedback's stamp [s]."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def planner_parameters(node, names):
    """Return the planner's values of ``names`` through its parameter service."""
    from rclpy.parameter_client import AsyncParameterClient
    params = AsyncParameterClient(node, 'planner')
    assert params.wait_for_services(timeout_sec=10.0)
    future = params.get_parameters(names)
    assert wait_until(future.done, 10.0, lambda t: rclpy.spin_once(node, timeout_sec=t))
    return [v.string_value or v.double_value for v in future.result().values]


@pytest.mark.parametrize('extra', (['--peak-height', '0.03'], []))
def test_cli_parabolic_leaves_the_planner_parameters(stack, client, extra):
    """``goal pose ... --motion parabolic``: arrives; the planner's parameters are unchanged."""
    from mover6_control.tools.goal_cli import run
    from mover6_control.tools.goal_convention import EXIT_ARRIVED
    node, _ = client
    home = node.send_joints(np.zeros((1, 6)), timeout=60.0)     # the goal is planned from home
    assert home.arrived, f'{home}\n{stack.report()}'
    assert node.values(node.controller_status)['goal_id'] == node.goal_id   # its own id
    lines = []
    assert run(['0.30', '0.05', '0.36', '0', '0', '0'], node, out=lines.append) == EXIT_ARRIVED
    names = ['motion', 'peak_height', 'path_motion']
    before = planner_parameters(node, names)
    code = run(['pose', '0.30', '-0.08', '0.32', '0', '0', '0', '--motion', 'parabolic'] + extra,
               node, out=lines.append)
    assert code == EXIT_ARRIVED, '\n'.join(lines) + stack.report()
    assert planner_parameters(node, names) == before == ['linear', 0.05, 'spline']
    # The planner's status named this goal; the controller's status the same goal id.
    planner = node.values(node.planner_status)
    assert planner['motion'] == 'parabolic' and planner['goal_id'] == node.goal_id
    assert node.values(node.controller_status)['goal_id'] == node.goal_id
