"""
End to end: the regressions of issue 31 the suite never had.

The sim bridge, the controller and the planner as processes with their shipped parameters.

- A second, rogue /joint_states publisher (stale states of the arm at home) appears while the
  arm moves: the controller faults and holds (zero commands) with the reason naming the
  publishers; once the rogue is gone it takes the states again and a goal arrives.
- A parameter set during a motion is never applied mid-motion: the motion keeps its profile
  and the set applies to the next motion.
- A cancel of a 10,000-point FollowJointTrajectory goal while the controller still plans it:
  the goal ends canceled, the arm at rest short of its end, and the next goal arrives.
"""

import time

from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointJog
from mover6_control.control.status import StatusKey
from mover6_control.nodes.messages.demand_messages import make_demands
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
import rclpy
from rclpy.action import ActionClient
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from ros_testing import ready_client, Stack, wait_until
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectoryPoint

pytestmark = pytest.mark.e2e
NAMES = [f'joint{k}' for k in range(1, 7)]


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start the three nodes with their shipped parameter files."""
    with Stack(tmp_path_factory.mktemp('regression_logs')) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a goal client once every node answers."""
    with ready_client(stack, lambda: GoalClient(name='regression_client'), timeout=60.0) as node:
        yield node


def state(client):
    """Return the controller's state now."""
    return client.values(client.controller_status).get(StatusKey.STATE)


def test_a_rogue_joint_states_publisher_holds_the_controller_with_the_reason(stack, client):
    commands = []
    client.create_subscription(JointJog, '/JointJog',
                               lambda m: commands.append((time.monotonic(), list(m.velocities))),
                               100)
    client.demands_pub.publish(make_demands(np.full((1, 6), 0.4), 'rogue-test'))
    assert client.spin_until(lambda: state(client) == 'executing', 20.0), client.controller_status
    rogue = client.create_publisher(JointState, '/joint_states', 10)
    stale = JointState(name=NAMES, position=[0.0] * 6)       # the arm at home, long ago

    def publish_stale():
        rogue.publish(stale)
    assert client.spin_until(lambda: state(client) == 'fault', 20.0, publish_stale), \
        client.controller_status
    message = client.controller_status.message
    assert 'publishers of /joint_states' in message and 'regression_client' in message, message
    held = time.monotonic()
    # The arm holds: zero commands while the rogue keeps publishing.
    assert client.spin_until(lambda: any(t > held + 0.3 for t, _ in commands), 10.0,
                             publish_stale)
    assert all(v == [0.0] * 6 for t, v in commands if t > held + 0.1), commands[-5:]
    assert state(client) == 'fault'
    client.destroy_publisher(rogue)
    assert client.spin_until(lambda: state(client) == 'idle', 20.0), client.controller_status
    outcome = client.send_joints([np.full(6, 0.2)], timeout=60.0)
    assert outcome.arrived, f'{outcome}\n{stack.report()}'


def test_a_parameter_set_during_a_motion_applies_after_it(stack, client):
    params = AsyncParameterClient(client, 'controller')
    assert params.wait_for_services(timeout_sec=20.0)

    def done(future):
        assert wait_until(future.done, 20.0, lambda t: rclpy.spin_once(client, timeout_sec=t))
        return future.result()
    client.demands_pub.publish(make_demands(np.full((1, 6), -0.3), 'param-test'))
    assert client.spin_until(lambda: state(client) == 'executing', 20.0)
    profile = client.values(client.controller_status).get(StatusKey.MOTION_PROFILE)
    result = done(params.set_parameters([Parameter('profile', value='trapezoidal')]))
    assert result.results[0].successful, result.results[0].reason
    seen = []
    assert client.spin_until(lambda: seen.append(client.values(client.controller_status))
                             or state(client) in ('idle', 'fault'), 60.0)
    during = {v.get(StatusKey.MOTION_PROFILE) for v in seen
              if v.get(StatusKey.STATE) == 'executing'}
    assert during == {profile}, during                  # never switched mid-motion
    outcome = client.send_joints([np.full(6, 0.1)], timeout=60.0)
    assert outcome.arrived, outcome
    assert client.values(client.controller_status).get(StatusKey.MOTION_PROFILE) == \
        'trapezoidal'
    done(params.set_parameters([Parameter('profile', value=profile)]))


def test_a_cancel_while_a_large_goal_is_planned_stops_it(stack, client):
    action = ActionClient(client, FollowJointTrajectory, '/controller/follow_joint_trajectory')
    assert action.wait_for_server(timeout_sec=20.0)

    def done(future, timeout=60.0):
        assert wait_until(future.done, timeout, lambda t: rclpy.spin_once(client, timeout_sec=t))
        return future.result()
    q0 = client.q.copy()
    end = q0 + np.array([0.8, 0.0, 0.0, 0.0, 0.0, 0.0])
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = NAMES
    goal.trajectory.points = [JointTrajectoryPoint(positions=[float(v) for v in q])
                              for q in np.linspace(q0, end, 10000)]
    handle = done(action.send_goal_async(goal))
    assert handle.accepted
    done(handle.cancel_goal_async())               # at once: the goal is still being planned
    response = done(handle.get_result_async(), 120.0)
    assert response.status == GoalStatus.STATUS_CANCELED, response.result.error_string
    assert client.spin_until(lambda: state(client) == 'idle', 30.0), client.controller_status
    q_stop = client.q.copy()
    assert np.abs(q_stop - end).max() > 0.1, q_stop            # stopped short of its end
    outcome = client.send_joints([np.full(6, 0.05)], timeout=60.0)
    assert outcome.arrived, f'{outcome}\n{stack.report()}'
    action.destroy()
