"""
The console's node on real rclpy (no browser): what it reads, sends and shows on its page.

The page's state is read from the node's parts (the panels' handles hold what the browser
shows); the browser itself is driven in test/e2e/test_e2e_console.py.
"""

import os

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import socket  # noqa: E402

from control_msgs.msg import JointJog  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PoseStamped, TwistStamped  # noqa: E402
from mover6_control.nodes.console.node import (ConsoleNode, is_loopback,  # noqa: E402
                                               parse_args)
from mover6_control.nodes.messages import conversions, demand_messages  # noqa: E402
from mover6_control.nodes.runtime.qos import STATUS_QOS  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from ros_testing import wait_until  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float32MultiArray  # noqa: E402

LIMIT = 30.0      # [s] generous limit of every wait
JOINTS = ('joint1', 'joint2', 'joint3', 'joint4', 'joint5', 'joint6')


def free_port():
    """Return a TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module."""
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def harness():
    """Yield the console node and a test node on one executor."""
    h = Harness()
    yield h
    h.close()


class Harness:
    """The console node (its page on a free port) and a test node that plays the graph."""

    def __init__(self):
        self.console = ConsoleNode(port=free_port())
        self.node = rclpy.create_node('console_tester')
        self.goals, self.jogs, self.twists = [], [], []
        self.node.create_subscription(TwistStamped, 'controller/delta_twist_cmds',
                                      self.twists.append, 10)
        self.node.create_subscription(PoseStamped, 'pose_goal/linear', self.goals.append, 10)
        self.node.create_subscription(JointJog, 'controller/delta_joint_cmds', self.jogs.append,
                                      10)
        self.states = self.node.create_publisher(JointState, 'joint_states', 10)
        self.demands = self.node.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.planner_status = self.node.create_publisher(DiagnosticStatus, 'planner/status',
                                                         STATUS_QOS)
        self.executor = SingleThreadedExecutor()
        for node in (self.console, self.node):
            self.executor.add_node(node)

    def spin(self, period):
        self.executor.spin_once(timeout_sec=period)

    def until(self, predicate):
        return wait_until(predicate, LIMIT, self.spin, 0.01)

    def publish_states(self, q):
        self.states.publish(conversions.make_joint_state(JOINTS, q))

    def answer(self):
        return self.console.goal.answer.content

    def close(self):
        self.executor.shutdown()
        self.console.destroy_node()
        self.node.destroy_node()


def test_without_the_nodes_the_page_says_what_is_missing(harness):
    """No controller in the graph: the page says so (the tester publishes the rest)."""
    assert harness.until(lambda: harness.console.status.shown is not None
                         and 'missing: the controller' in harness.console.status.shown)
    shown = harness.console.status.shown
    assert 'the controller (controller/status has no publisher)' in shown
    assert 'missing: /joint_states' not in shown and 'missing: the planner' not in shown
    harness.node.destroy_publisher(harness.states)
    assert harness.until(lambda: 'missing: /joint_states' in harness.console.status.shown)


def test_the_arm_follows_the_joint_states_and_the_demands_are_drawn(harness):
    q = np.array([0.2, 0.1, -0.1, 0.3, 0.2, -0.4])
    assert harness.until(lambda: (harness.publish_states(q), harness.console.view.q)[1]
                         is not None and np.allclose(harness.console.view.q, q))
    Q = np.linspace(np.zeros(6), q, 5)
    harness.demands.publish(demand_messages.make_demands(Q, 'g1'))
    assert harness.until(lambda: 'demand' in harness.console.view.paths)


def test_plan_without_joint_states_is_refused_on_the_page_and_counted(harness):
    plan = harness.console.page_wrap('console plan', harness.console.actions.plan)
    plan(harness.console.goal.request())
    assert harness.answer().startswith('Answer: refused (invalid_input): no /joint_states')
    assert harness.console.guard.refused == {'console plan': 1}


def test_a_field_that_is_no_number_is_refused_with_its_name(harness):
    harness.console.goal.numbers[1].value = '-'
    go = harness.console.page_wrap('console go', lambda _: harness.console.actions.go(
        harness.console.goal.request()))
    go(None)
    assert 'Y [m] is not a number' in harness.answer()
    assert harness.goals == []


def test_go_sends_the_goal_and_shows_the_planners_refusal_with_a_ghost(harness):
    harness.publish_states(np.zeros(6))
    assert harness.until(lambda: harness.console.q is not None)
    harness.console.goal.set_numbers((0.9, 0.0, 0.4, 0.0, 0.0, 0.0))
    request = harness.console.goal.request()
    assert harness.until(lambda: harness.console.actions.publisher(
        PoseStamped, 'pose_goal/linear').get_subscription_count() > 0)
    harness.console.actions.go(request)
    assert harness.until(lambda: harness.goals)
    sent = conversions.pose_goal_from_msg(harness.goals[0]).matrix
    assert np.allclose(sent, request.T, atol=1e-6)
    stamp = harness.goals[0].header.stamp
    values = {'state': 'ready', 'goal_stamp': f'{stamp.sec}.{stamp.nanosec:09d}',
              'result': 'refused', 'reason': 'out_of_reach'}
    harness.planner_status.publish(conversions.make_status(
        'planner', 'ERROR', 'goal refused (out_of_reach): far', values))
    assert harness.until(lambda: 'the planner refused the goal (out_of_reach)' in
                         harness.answer())
    assert 'ghost: the farthest reachable pose on the straight line' in harness.answer()
    assert harness.console.view.ghost.show_visual


def test_a_joint_jog_is_sent_while_held_then_one_zero(harness):
    jog = harness.console.jog
    jog.joints.give([0.0, 0.1, 0.0, 0.0, 0.0, 0.0], jog.clock())
    assert harness.until(lambda: any(m.velocities[1] == pytest.approx(0.1)
                                     for m in harness.jogs))
    assert harness.until(lambda: harness.jogs[-1].velocities[1] == 0.0)
    assert list(harness.jogs[-1].joint_names) == list(JOINTS)


def test_a_pad_button_jogs_along_its_axis_then_stops(harness):
    harness.console.jog.press('-Z')
    assert harness.until(lambda: any(m.twist.linear.z < 0.0 for m in harness.twists))
    moving = next(m for m in harness.twists if m.twist.linear.z < 0.0)
    assert moving.twist.linear.z == pytest.approx(-0.03)
    assert moving.header.frame_id == 'base_link'
    assert harness.until(lambda: harness.twists[-1].twist.linear.z == 0.0)


@pytest.mark.parametrize('host, loopback', [('127.0.0.1', True), ('localhost', True),
                                            ('::1', True), ('0.0.0.0', False),
                                            ('192.168.1.5', False), ('arm.local', False)])
def test_only_loopback_is_served_without_a_warning(host, loopback):
    assert is_loopback(host) == loopback


def test_the_default_address_is_loopback():
    options = parse_args([])
    assert (options.host, options.port) == ('127.0.0.1', 8080)
