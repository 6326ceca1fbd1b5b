"""
End to end against the vendor driver: the three nodes as processes, the bridge in vendor mode.

The sim bridge behaves like the Mover6's cpr driver (fractions of the maximum speed, 20 Hz
cycle and /joint_states, whole encoder ticks, last command held); the controller sends
fraction_of_max. Goals go in as a user sends them; arrival is judged from /joint_states.
"""

from control_msgs.msg import JointJog
from mover6_control.kinematics.arm import mover6, MOVER6_TICK_SIZE
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.messages.conversions import status_values
from mover6_control.parameters import CONTROLLER
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
from ros_testing import (assert_settled, GOAL_TOLERANCE, POSITION_TOLERANCE, ready_client,
                         Stack)

pytestmark = pytest.mark.e2e

ARM = mover6()
TICK = np.array(MOVER6_TICK_SIZE)
TOL = np.maximum(GOAL_TOLERANCE, TICK)  # goal tolerance in use: the shipped one, one tick on J5/J6
# The settle tolerance in use behind a driver with a cycle: one of its ticks per joint.
SETTLE = np.array(CONTROLLER['driver_tick_size'].default)
FLOAT32 = 1e-6                         # /joint_demands carry float32 [rad]
# 5 cm forward-left and 8 cm down from home, tool along +x (A=0, B=pi/2, C=0).
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
# The stack as ./run.sh launch --jog-units fraction-of-max starts it (the stack definition's
# parameters, its state_timeout too).
OPTIONS = {'jog_units': 'fraction_of_max'}


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start sim_bridge (vendor_driver), controller (fraction_of_max) and planner."""
    with Stack(tmp_path_factory.mktemp('e2e_vendor_logs'), options=OPTIONS) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a goal client that also records every /JointJog, once every node answers."""
    def make():
        node = GoalClient(name='e2e_vendor_client')
        node.jogs = []
        node.create_subscription(JointJog, 'JointJog',
                                 lambda msg: node.jogs.append(np.array(msg.velocities)), 100)
        return node
    with ready_client(stack, make) as node:
        # The planner's demands reach the controller only once DDS has matched them (a message
        # before that is lost): wait until this process sees both ends (itself being one of
        # each).
        assert node.spin_until(lambda: node.count_publishers('joint_demands') >= 2
                               and node.count_subscribers('joint_demands') >= 2, 30.0), \
            'planner or controller not on /joint_demands\n' + stack.report()
        yield node


def tool_travel(q, dq):
    """Return the most the tool moves [m] for joint steps of up to ``dq`` (n,) at ``q``."""
    p = fk(ARM, q)[:3, 3]
    return sum(np.linalg.norm(fk(ARM, q + step)[:3, 3] - p) for step in np.diag(dq))


def assert_at_rest(client, stack, q_goal):
    """Assert the arm reports whole ticks within a tick of ``q_goal``, commanded zero, still."""
    # After 'arrived' the controller settles (at most settle_time), then idles on a zero command.
    assert client.spin_until(
        lambda: status_values(client.controller_status).get('state') == 'idle', 10.0), \
        stack.report()
    # Arrived inside the goal tolerance, then settled to one tick per joint.
    assert_settled(client.controller_status, stack, settle_tolerance=SETTLE + FLOAT32,
                   goal_tolerance=TOL + FLOAT32)
    q = client.q.copy()
    np.testing.assert_allclose(q / TICK, np.round(q / TICK), atol=1e-6)   # encoder readings
    assert np.all(np.abs(q - q_goal) <= SETTLE + FLOAT32), \
        f'{(q - q_goal) / TICK}\n{stack.report()}'
    jogs = len(client.jogs)
    assert client.spin_until(lambda: len(client.jogs) >= jogs + 20, 10.0)  # 0.2 s of commands
    assert not np.any(client.jogs[-1]), client.jogs[-1]
    stamp = [client.q]
    for _ in range(3):                                   # three more readings: no motion
        assert client.spin_until(lambda: client.q is not stamp[0], 5.0)
        stamp[0] = client.q
        np.testing.assert_array_equal(client.q, q)


def test_controller_reports_the_driver_units_and_tolerance(stack, client):
    values = status_values(client.controller_status)
    assert values['jog_units'] == 'fraction_of_max', f'{values}\n{stack.report()}'
    tolerance = np.array([float(v) for v in values['goal_tolerance'].split()])
    np.testing.assert_allclose(tolerance, TOL, atol=1e-6)


def test_pose_goal_arrives_on_the_vendor_driver(stack, client):
    """A PoseStamped goal: the arm arrives within a tick per joint and a few mm at the tool."""
    client.jogs.clear()
    outcome = client.send_pose(GOAL, timeout=60.0)
    assert outcome.arrived, f'{outcome}\n{stack.report()}'
    demands = client.last_demands
    assert demands is not None and demands.shape[1] == 6 and demands.shape[0] >= 2
    assert_at_rest(client, stack, demands[-1])
    # Wider than the planner's tolerance by the tool's travel for a tick per joint (a wrist
    # tick is 6 mrad): the arm settles to whole ticks.
    assert np.linalg.norm(fk(ARM, client.q)[:3, 3] - GOAL[:3, 3]) <= (
        POSITION_TOLERANCE + tool_travel(demands[-1], TICK))
    jogs = np.array(client.jogs)
    assert np.all(np.abs(jogs) <= 1.0) and np.abs(jogs).max() > 0.1     # fractions, used
    values = status_values(client.controller_status)
    print(f"FIGURE vendor: oldest /joint_states a tick used {values.get('max_states_age')} s, "
          f"longest tick gap {values.get('max_tick_gap')} s")


def test_small_wrist_move_arrives(stack, client):
    """J5 and J6 by 0.03 and -0.02 rad: all under the driver's dead zone at the default gain."""
    assert client.spin_until(lambda: client.q is not None, 10.0)
    q_goal = client.q + np.array([0.0, 0.0, 0.0, 0.0, 0.03, -0.02])
    outcome = client.send_joints(q_goal[None], timeout=60.0)
    assert outcome.arrived, f'{outcome}\n{stack.report()}'
    assert_at_rest(client, stack, q_goal)
