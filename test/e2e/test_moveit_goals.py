"""
End to end: FollowJointTrajectory goals shaped as MoveIt sends them, to the controller's server.

MoveIt is not installed here, so this test plays ``move_group``'s trajectory execution: the
simulator and the controller run as processes in a namespace, and an rclpy ``ActionClient`` in
that namespace finds the server by the name MoveIt's simple controller manager makes from
``config/moveit/moveit_controllers.yaml`` (``<controller>/<action_ns>``, relative to
move_group's namespace). Its goals are what MoveIt's time parameterization emits: the first point
at ``time_from_start`` 0 at the current state, every point with positions, velocities and
accelerations within ``joint_limits.yaml`` scaled by its default factors, no tolerances (MoveIt
leaves them empty), here with the joints in another order than the controller's. Then the
tolerances a client may give (by joint name, in another order), a partial joint set, and a
cancel (MoveIt's stop).
"""

import os

from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from mover6_control.kinematics.arm import mover6
from mover6_control.tools.goal_cli import GoalClient
from mover6_control.tools.moveit_config import MOVEIT_DIR
import numpy as np
import pytest
import rclpy
from rclpy.action import ActionClient
from rclpy.action.graph import get_action_names_and_types
from rclpy.duration import Duration
from ros_testing import SETTLE_TOLERANCE, settled_q, Stack, wait_until
from trajectory_msgs.msg import JointTrajectoryPoint
import yaml

pytestmark = pytest.mark.e2e

NAMESPACE = f'/moveit_goals_{os.getpid()}'
ARM = mover6()
NAMES = list(ARM.joint_names)
ORDER = [2, 0, 5, 1, 4, 3]           # another order than the controller's: joint3, joint1, ...
Result = FollowJointTrajectory.Result
POINTS = 12                          # MoveIt's time parameterization emits a point every ~0.1 s


def moveit_file(name):
    """Return a file of config/moveit/ parsed."""
    with open(os.path.join(MOVEIT_DIR, name)) as f:
        return yaml.safe_load(f)


def action_name_as_moveit_makes_it(namespace):
    """Return the action MoveIt's simple controller manager in ``namespace`` sends goals to."""
    manager = moveit_file('moveit_controllers.yaml')['moveit_simple_controller_manager']
    (controller,) = manager['controller_names']
    relative = f'{controller}/{manager[controller]["action_ns"]}'
    return f'{namespace}/{relative}' if not relative.startswith('/') else relative


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start the simulator and the controller as processes in ``NAMESPACE``."""
    ns = ('-r', f'__ns:={NAMESPACE}')
    with Stack(tmp_path_factory.mktemp('moveit_logs'), names=('sim_bridge', 'controller'),
               ros_args={'sim_bridge': ns, 'controller': ns}) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return (node in the namespace, action client at MoveIt's name) once the arm is ready."""
    rclpy.init(args=['--ros-args', '-r', f'__ns:={NAMESPACE}'])
    node = GoalClient(name='moveit_goals')
    try:
        problem = node.wait_ready(timeout=30.0, need_planner=False)
        assert problem is None, f'{problem}\n{stack.report()}'
        action = ActionClient(node, FollowJointTrajectory,
                              action_name_as_moveit_makes_it(node.get_namespace()))
        assert action.wait_for_server(timeout_sec=20.0), stack.report()
        yield node, action
        action.destroy()
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def spin(node):
    """Return a spin function for ``wait_until``."""
    return lambda t: rclpy.spin_once(node, timeout_sec=t)


def moveit_trajectory(q_start, q_goal, order=ORDER):
    """
    Return a goal from ``q_start`` to ``q_goal`` as MoveIt's time parameterization makes one.

    A quintic in time per joint, all joints together, its duration the shortest that keeps every
    joint within joint_limits.yaml times MoveIt's default scaling factors; ``POINTS`` points, the
    first at t = 0 at ``q_start`` (at rest), each with positions, velocities and accelerations,
    the joints in ``order``.
    """
    config = moveit_file('joint_limits.yaml')
    limits = config['joint_limits']
    v_max = np.array([limits[n]['max_velocity'] for n in NAMES]) * config[
        'default_velocity_scaling_factor']
    a_max = np.array([limits[n]['max_acceleration'] for n in NAMES]) * config[
        'default_acceleration_scaling_factor']
    d = np.asarray(q_goal, dtype=float) - np.asarray(q_start, dtype=float)
    # A quintic's peak speed is 1.875 d / T, its peak acceleration 5.7735 d / T^2.
    T = max(np.max(1.875 * np.abs(d) / v_max), np.max(np.sqrt(5.7735 * np.abs(d) / a_max)))
    T = float(np.ceil(T * 10.0) / 10.0)
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = [NAMES[i] for i in order]
    for t in np.linspace(0.0, T, POINTS):
        s = t / T
        pos = 10 * s**3 - 15 * s**4 + 6 * s**5
        vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
        acc = (60 * s - 180 * s**2 + 120 * s**3) / T**2
        q, qd, qdd = q_start + d * pos, d * vel, d * acc
        point = JointTrajectoryPoint(positions=[float(q[i]) for i in order],
                                     velocities=[float(qd[i]) for i in order],
                                     accelerations=[float(qdd[i]) for i in order])
        point.time_from_start = Duration(seconds=float(t)).to_msg()
        goal.trajectory.points.append(point)
    return goal, T


def send(node, action, goal, feedback=None):
    """Send ``goal``; return its goal handle (accepted: the server accepts every goal)."""
    future = action.send_goal_async(goal, feedback_callback=feedback)
    assert wait_until(future.done, 20.0, spin(node))
    handle = future.result()
    assert handle.accepted
    return handle


def result_of(node, handle, timeout=60.0):
    """Wait for and return ``(status, Result)`` of ``handle``."""
    future = handle.get_result_async()
    assert wait_until(future.done, timeout, spin(node))
    response = future.result()
    return response.status, response.result


def at_rest(node, samples=20):
    """Return True when the next ``samples`` /joint_states positions do not move (< 0.1 mrad)."""
    seen = []

    def collect():
        seen.append(node.q.copy())
        return len(seen) >= samples

    assert wait_until(collect, 10.0, spin(node), period=0.02)
    return np.abs(np.array(seen) - seen[0]).max() < 1e-4


def test_the_server_is_where_moveit_looks_in_the_namespace(client):
    """The action named as MoveIt makes the name, in the stack's namespace, is served."""
    node, _ = client
    name = action_name_as_moveit_makes_it(NAMESPACE)
    assert name == f'{NAMESPACE}/controller/follow_joint_trajectory'
    actions = dict(get_action_names_and_types(node))
    assert actions.get(name) == ['control_msgs/action/FollowJointTrajectory']


def test_moveit_timed_trajectory_is_followed_as_timed(stack, client):
    """First point at t = 0 at the current state, joints reordered: SUCCESSFUL on its timing."""
    node, action = client
    q_start = node.q.copy()
    q_goal = q_start + np.array([0.3, -0.15, 0.2, 0.1, -0.2, 0.25])
    goal, duration = moveit_trajectory(q_start, q_goal)
    feedback = []
    handle = send(node, action, goal, feedback=lambda msg: feedback.append(msg.feedback))
    status, result = result_of(node, handle)
    assert status == GoalStatus.STATUS_SUCCEEDED
    assert result.error_code == Result.SUCCESSFUL, f'{result.error_string}\n{stack.report()}'
    assert 'timing' not in result.error_string          # followed as given, not re-timed
    # The reference is the goal's timing: its time runs to the trajectory's duration.
    longest = max(Duration.from_msg(f.desired.time_from_start).nanoseconds * 1e-9
                  for f in feedback)
    assert longest == pytest.approx(duration, abs=0.01)
    assert np.abs(settled_q(node, stack) - q_goal).max() <= SETTLE_TOLERANCE


def test_tolerances_by_name_in_another_order(stack, client):
    """Goal and path tolerances by joint name (reordered, -1 = none): SUCCESSFUL within them."""
    node, action = client
    q_start = node.q.copy()
    q_goal = q_start + np.array([-0.2, 0.1, -0.1, 0.0, 0.15, -0.2])
    goal, _ = moveit_trajectory(q_start, q_goal)
    goal.path_tolerance = [JointTolerance(name=NAMES[i], position=0.2) for i in ORDER[:5]]
    goal.path_tolerance.append(JointTolerance(name=NAMES[ORDER[5]], position=-1.0))
    goal.goal_tolerance = [JointTolerance(name=NAMES[i], position=0.01) for i in ORDER]
    status, result = result_of(node, send(node, action, goal))
    assert result.error_code == Result.SUCCESSFUL, f'{result.error_string}\n{stack.report()}'
    # The goal's 0.01 rad is looser than the controller's own: it still settles within those.
    assert np.abs(settled_q(node, stack) - q_goal).max() <= SETTLE_TOLERANCE


def test_path_tolerance_left_aborts_and_stops_the_arm(stack, client):
    """A path tolerance no tracking meets (10 urad on one joint): aborted, the arm stopped."""
    node, action = client
    q_start = node.q.copy()
    q_goal = q_start + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5])
    goal, _ = moveit_trajectory(q_start, q_goal)
    goal.path_tolerance = [JointTolerance(name='joint6', position=1e-5)]
    status, result = result_of(node, send(node, action, goal))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == Result.PATH_TOLERANCE_VIOLATED, result.error_string
    assert 'joint6' in result.error_string
    assert at_rest(node)
    assert np.abs(node.q - q_goal).max() > 0.01          # stopped short of the goal


def test_partial_joint_set_is_refused_and_nothing_moves(stack, client):
    """
    Five joints of six, reordered: INVALID_JOINTS with the reason; the arm does not move.

    As joint_trajectory_controller's default (allow_partial_joints_goal false). MoveIt sends the
    controller's six joints for the group mover6_arm, the only group of this configuration.
    """
    node, action = client
    q_start = node.q.copy()
    goal, _ = moveit_trajectory(q_start, q_start + 0.2, order=ORDER[:5])
    status, result = result_of(node, send(node, action, goal))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == Result.INVALID_JOINTS
    assert 'exactly' in result.error_string
    assert at_rest(node)
    assert np.abs(node.q - q_start).max() < 1e-3


def test_cancel_stops_the_arm(stack, client):
    """A cancel (MoveIt's stop): the goal ends canceled, the arm at rest short of the goal."""
    node, action = client
    q_start = node.q.copy()
    q_goal = q_start + np.array([-0.8, 0.0, 0.0, 0.0, 0.0, 0.0])
    goal, _ = moveit_trajectory(q_start, q_goal)
    handle = send(node, action, goal)
    assert wait_until(lambda: np.abs(node.q - q_start).max() > 0.1, 20.0, spin(node)), (
        stack.report())
    cancel = handle.cancel_goal_async()
    assert wait_until(cancel.done, 10.0, spin(node))
    status, result = result_of(node, handle)
    assert status == GoalStatus.STATUS_CANCELED, result.error_string
    assert at_rest(node)
    assert np.abs(node.q - q_goal).max() > 0.1
