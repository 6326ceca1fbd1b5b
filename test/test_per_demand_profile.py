"""A demand's own profile: parsed from its label, timing that motion only (issue 11)."""

import os
import time

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from mover6_control.control.controller_core import ControllerConfig, ControllerCore
from mover6_control.control.velocity_laws import LawConfig, plan_motion
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes import conversions
from mover6_control.nodes.controller_node import ControllerNode
from mover6_control.tools.goal_cli import EXIT_ARRIVED, EXIT_REFUSED, Outcome, run
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

ARM = mover6()
NAMES = [f'joint{i}' for i in range(1, 7)]
NS = f'per_demand_profile_test_{os.getpid()}'
GOAL = np.array([0.3, -0.2, 0.2, 0.1, -0.1, 0.3])


def labelled(label):
    """Return a one-row demand whose first dimension is labelled ``label``."""
    msg = conversions.make_demands(GOAL[None])
    msg.layout.dim[0].label = label
    return msg


# --- the label -------------------------------------------------------------------------------

def test_make_demands_writes_the_profile_after_the_goal_id():
    msg = conversions.make_demands(GOAL[None], 'g-1', 'cubic')
    assert msg.layout.dim[0].label == 'waypoints goal g-1 profile cubic'
    assert conversions.demand_id_from_msg(msg) == 'g-1'
    assert conversions.demand_profile_from_msg(msg) == 'cubic'
    np.testing.assert_allclose(conversions.demands_from_msg(msg), GOAL[None], atol=1e-6)


@pytest.mark.parametrize('label, goal_id, profile', [
    ('waypoints', '', ''),
    ('waypoints goal 1.000000000-3', '1.000000000-3', ''),          # what the planner wrote
    ('waypoints profile quintic', '', 'quintic'),                   # typed, no goal id
    ('waypoints profile septic goal abc', 'abc', 'septic'),          # any order
    ('waypoints  goal  abc   profile  bspline ', 'abc', 'bspline'),  # any spacing
    ('rows', '', ''),                                               # not ours: no options
])
def test_labels_ros2_topic_pub_can_type(label, goal_id, profile):
    msg = labelled(label)
    assert conversions.demand_id_from_msg(msg) == goal_id
    assert conversions.demand_profile_from_msg(msg) == profile


def test_a_flat_demand_carries_no_options():
    msg = Float32MultiArray()
    msg.data = [float(v) for v in GOAL]
    assert conversions.demand_options_from_msg(msg) == {}


@pytest.mark.parametrize('label', ['waypoints profile', 'waypoints goal a profile',
                                   'waypoints speed fast', 'waypoints profile cubic profile x'])
def test_a_malformed_label_is_refused_with_the_grammar(label):
    with pytest.raises(InvalidInputError, match=r'waypoints \[goal <id>\] \[profile <name>\]'):
        conversions.demand_profile_from_msg(labelled(label))


def test_goal_frame_carries_a_profile_and_stays_a_frame():
    msg = PoseStamped()
    msg.header.frame_id = 'base_link profile quintic'
    assert conversions.goal_profile_from_header(msg.header) == 'quintic'
    conversions.pose_stamped_to_matrix(msg, 'base_link')        # the frame is still checked
    msg.header.frame_id = 'world profile quintic'
    with pytest.raises(InvalidInputError, match='expected "base_link"'):
        conversions.pose_stamped_to_matrix(msg, 'base_link')
    msg.header.frame_id = 'base_link'
    assert conversions.goal_profile_from_header(msg.header) == ''
    msg.header.frame_id = 'base_link profile a b'
    with pytest.raises(InvalidInputError, match='profile <name>'):
        conversions.goal_profile_from_header(msg.header)


# --- the goal command ------------------------------------------------------------------------

class RecordingClient:
    """Stands in for GoalClient: records how each goal is sent, 'arrives' at once."""

    arm = ARM

    def __init__(self):
        self.sent = []

    def wait_ready(self, **kwargs):
        return None

    def send_pose(self, T, frame_id='base_link', **kwargs):
        self.sent.append(('pose', frame_id, kwargs.get('motion')))
        return Outcome(EXIT_ARRIVED, 'arrived')

    def send_path(self, poses, frame_id='base_link', shape=None, **kwargs):
        self.sent.append(('path', frame_id, shape, len(poses)))
        return Outcome(EXIT_ARRIVED, 'arrived')

    def send_joints(self, Q, profile='', **kwargs):
        self.sent.append(('joints', profile))
        return Outcome(EXIT_ARRIVED, 'arrived')


@pytest.mark.parametrize('argv, sent', [
    (['0.3', '0.05', '0.36', '0', '0', '0', '--profile', 'quintic'],
     ('pose', 'base_link profile quintic', None)),
    (['0.3', '0.05', '0.36', '0', '0', '0'], ('pose', 'base_link', None)),
    (['path', '--shape', 'joint', '--profile', 'cubic', '--via', '0.32', '0', '0.38', '0', '0',
      '0', '0.30', '0.08', '0.34', '0', '0', '0'],
     ('path', 'base_link profile cubic', 'joint', 2)),
    (['joints', '0.2', '0.1', '0.3', '0', '0.4', '0', '--profile', 'bspline'],
     ('joints', 'bspline')),
])
def test_goal_command_sends_the_profile_with_the_goal(argv, sent):
    client = RecordingClient()
    assert run(argv, client, out=lambda text: None) == EXIT_ARRIVED
    assert client.sent == [sent]


def test_goal_command_refuses_an_unknown_profile(capsys):
    with pytest.raises(SystemExit) as exit_:
        run(['0.3', '0.05', '0.36', '0', '0', '0', '--profile', 'banana'], RecordingClient())
    assert exit_.value.code == EXIT_REFUSED
    assert "invalid choice: 'banana'" in capsys.readouterr().err


# --- the core --------------------------------------------------------------------------------

def started_core(profile='trapezoidal'):
    core = ControllerCore(ARM, ControllerConfig(law=LawConfig(profile=profile)))
    core.on_joint_states(0.0, np.zeros(6))
    core.tick(0.0)
    return core


def test_a_demands_profile_times_that_motion_and_leaves_the_configuration():
    core = started_core('trapezoidal')
    config = core.config
    core.on_demands(0.0, GOAL[None], 'g', profile='quintic')
    assert core.config is config and core.config.law.profile == 'trapezoidal'
    expected = plan_motion(LawConfig(profile='quintic'), np.zeros(6), GOAL[None],
                           ARM.velocity_limits)
    assert core.plan.duration == pytest.approx(expected.duration)
    values = core.status().values
    assert values['profile'] == 'trapezoidal'            # the parameter in force
    assert values['motion_profile'] == 'quintic'         # the law of this motion
    assert 'quintic' in core.status().message
    # The next demand without a profile is timed by the parameter's law again.
    core.on_demands(0.1, (GOAL / 2)[None], 'h')
    assert core.status().values['motion_profile'] == 'trapezoidal'


def test_an_unknown_profile_is_refused_with_the_reason_and_the_motion_kept():
    core = started_core()
    motion = core.on_demands(0.0, GOAL[None], 'g')
    with pytest.raises(InvalidInputError, match='profile must be one of'):
        core.on_demands(0.1, (GOAL / 2)[None], 'bad', profile='banana')
    assert core.motion_id == motion
    values = core.status().values
    assert values['rejected_goal_id'] == 'bad' and 'banana' in values['rejected']
    assert core.config.law.profile == 'trapezoidal'


# --- the node --------------------------------------------------------------------------------

class Arm(Node):
    """Integrate JointJog into /joint_states and keep the controller's statuses."""

    def __init__(self, context):
        super().__init__('arm', context=context, namespace=NS)
        self.q, self.qd, self.last = np.zeros(6), np.zeros(6), time.monotonic()
        self.statuses = []
        self.state_pub = self.create_publisher(JointState, 'joint_states', 10)
        self.demand_pub = self.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.create_subscription(JointJog, 'JointJog', self.on_jog, 10)
        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(DiagnosticStatus, 'controller/status', self.statuses.append, qos)
        self.create_timer(0.02, self.on_timer)

    def on_jog(self, msg):
        self.qd = np.array(conversions.joint_jog_from_msg(msg)[1])

    def on_timer(self):
        now = time.monotonic()
        self.q = self.q + self.qd * min(now - self.last, 0.05)
        self.last = now
        self.state_pub.publish(conversions.make_joint_state(NAMES, self.q, self.qd))

    def status(self):
        return conversions.status_values(self.statuses[-1]) if self.statuses else {}


@pytest.fixture(scope='module')
def ros():
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    context = rclpy.Context()
    rclpy.init(context=context)
    controller = ControllerNode(context=context, namespace=NS, parameter_overrides=[
        Parameter('profile', value='trapezoidal')])
    arm = Arm(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(arm)

    def spin_until(predicate, timeout=30.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
            if predicate():
                return True
        raise AssertionError(f'timed out; last status {arm.status()}')

    yield controller, arm, spin_until
    executor.shutdown()
    controller.destroy_node()
    arm.destroy_node()
    rclpy.try_shutdown(context=context)


def test_node_times_a_demand_by_its_profile_without_touching_the_parameter(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    arm.demand_pub.publish(labelled('waypoints goal typed-1 profile quintic'))
    spin_until(lambda: arm.status().get('goal_id') == 'typed-1'
               and arm.status().get('result') == 'arrived')
    assert arm.status()['motion_profile'] == 'quintic'
    assert arm.status()['profile'] == 'trapezoidal'
    assert controller.get_parameter('profile').value == 'trapezoidal'
    spin_until(lambda: arm.status().get('state') == 'idle')


def test_node_refuses_an_unknown_profile_with_the_reason(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    arm.demand_pub.publish(labelled('waypoints goal typed-2 profile banana'))
    spin_until(lambda: arm.status().get('rejected_goal_id') == 'typed-2')
    assert 'banana' in arm.status()['rejected']
    assert controller.get_parameter('profile').value == 'trapezoidal'
