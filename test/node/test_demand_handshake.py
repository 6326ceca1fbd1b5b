"""
The planner-controller handshake, with real rclpy nodes in one process: each way a demand ends.

With the real planner and controller: taken, refused (the controller's collision check, off in
the planner), not ready (a controller that has no joint states). With the real planner and a
probe answering as the controller does (``DemandAnswers``, the controller's own part):
superseded. The planner's ``DemandHandshake`` built alone on a node: a demand sent before any
reader is matched is sent again when one matches (no timer), and a demand nobody answers ends
``NO_CONTROLLER``.
"""

from actionlib_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.controller.demand_answers import DemandAnswers
from mover6_control.nodes.controller.node import ControllerNode
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.messages.demand_acks import ack_from_msg, ACK_QOS, ACK_TOPIC, Answer
from mover6_control.nodes.planner.handshake import DemandHandshake, HandshakeEnd
from mover6_control.nodes.planner.node import PlannerNode
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from ros_testing import spin_until
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

pytestmark = pytest.mark.node
ARM = mover6()
HOME = np.zeros(6)
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
# A keep-out box around GOAL's tool position, clear of the arm at HOME (a box the arm stands
# in is refused at the parameter): a controller checking it refuses the motion.
BOX_AT_GOAL = [0.25, 0.0, 0.31, 0.35, 0.10, 0.38]


class Probe(Node):
    """Publishes states and goals; records demands, the planner's statuses and the answers."""

    def __init__(self):
        super().__init__('handshake_probe')
        self.demands, self.statuses, self.answers = [], [], []
        self.state_pub = self.create_publisher(JointState, 'joint_states', 10)
        self.pose_pub = self.create_publisher(PoseStamped, 'pose_goal', 10)
        self.create_subscription(Float32MultiArray, 'joint_demands', self.demands.append, 10)
        self.create_subscription(DiagnosticStatus, 'planner/status', self.statuses.append,
                                 QoSProfile(depth=50, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.create_subscription(GoalStatus, ACK_TOPIC,
                                 lambda m: self.answers.append(ack_from_msg(m)), ACK_QOS)

    def publish_state(self):
        self.state_pub.publish(conversions.make_joint_state(ARM.joint_names, HOME, np.zeros(6)))

    def send_goal(self):
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.pose = conversions.matrix_to_pose(GOAL)
        self.pose_pub.publish(msg)

    def said(self, seq, result):
        """Return the planner's statuses about goal ``seq`` with ``result``."""
        return [conversions.status_values(m) for m in self.statuses
                if conversions.status_values(m).get('goal_seq') == str(seq)
                and conversions.status_values(m).get('result') == result]


@pytest.fixture
def ros():
    """Yield (executor, add): ``add(node)`` spins it on the executor; all ends after the test."""
    rclpy.init()
    executor = SingleThreadedExecutor()
    nodes = []

    def add(node):
        nodes.append(node)
        executor.add_node(node)
        return node
    yield executor, add
    executor.shutdown()
    for node in reversed(nodes):
        node.destroy_node()
    rclpy.try_shutdown()


def ready(executor, probe, planner):
    """Wait until the planner has states and the probe reaches it."""
    assert spin_until(executor, lambda: probe.pose_pub.get_subscription_count() > 0
                      and planner.states.q is not None, each=probe.publish_state)


def controller_idle(executor, probe, controller):
    """Wait until the controller has valid joint states and is idle: it can take a demand."""
    def idle():
        with controller.lock:
            return controller.core.state == 'idle'
    assert spin_until(executor, idle, each=probe.publish_state)


def test_a_demand_the_controller_takes(ros):
    """Received, then taken: the answers name the goal and its motion; nothing waits."""
    executor, add = ros
    planner = add(PlannerNode())
    controller = add(ControllerNode())
    probe = add(Probe())
    ready(executor, probe, planner)
    controller_idle(executor, probe, controller)
    probe.send_goal()
    assert spin_until(executor, lambda: any(a.answer == Answer.TAKEN for a in probe.answers),
                      each=probe.publish_state)
    goal_id = probe.said(1, 'planned')[0]['goal_id']
    assert [(a.goal_id, a.answer) for a in probe.answers] == [(goal_id, Answer.RECEIVED),
                                                              (goal_id, Answer.TAKEN)]
    assert probe.answers[-1].text.startswith('motion ')
    assert spin_until(executor, lambda: planner.delivery.handshake.waiting() == 0,
                      each=probe.publish_state)
    assert probe.said(1, 'refused') == [] and probe.said(1, 'failed') == []


def test_a_demand_the_controller_refuses(ros):
    """The controller's collision check (off in the planner) refuses it: controller_refused."""
    executor, add = ros
    planner = add(PlannerNode(parameter_overrides=[Parameter('collision_check', value=False)]))
    box = Parameter('keep_out_boxes', value=BOX_AT_GOAL)
    controller = add(ControllerNode(parameter_overrides=[box]))
    probe = add(Probe())
    ready(executor, probe, planner)
    controller_idle(executor, probe, controller)    # not ready would be the other answer
    probe.send_goal()
    assert spin_until(executor, lambda: probe.said(1, 'refused'), each=probe.publish_state)
    values = probe.said(1, 'refused')[0]
    assert values['reason'] == 'controller_refused'
    assert [a.answer for a in probe.answers] == [Answer.RECEIVED, Answer.REFUSED]
    assert probe.said(1, 'planned')          # said before the refusal, as always
    assert planner.delivery.handshake.waiting() == 0


def test_a_demand_a_controller_without_states_takes_not(ros):
    """The controller has no joint states (they go elsewhere): controller_not_ready."""
    executor, add = ros
    planner = add(PlannerNode())
    add(ControllerNode(cli_args=['--ros-args', '-r', 'joint_states:=elsewhere']))
    probe = add(Probe())
    ready(executor, probe, planner)
    probe.send_goal()
    assert spin_until(executor, lambda: probe.said(1, 'refused'), each=probe.publish_state)
    values = probe.said(1, 'refused')[0]
    assert values['reason'] == 'controller_not_ready'
    assert [a.answer for a in probe.answers] == [Answer.RECEIVED, Answer.NOT_READY]
    assert 'waiting_for_states' in probe.answers[-1].text


def test_a_demand_overtaken_by_a_later_one_is_superseded(ros):
    """The controller never had goal 1, and had goal 2: goal 1 fails superseded, not resent."""
    executor, add = ros
    planner = add(PlannerNode())
    probe = add(Probe())
    answers = DemandAnswers(probe, lambda: probe.get_clock().now().nanoseconds)
    ready(executor, probe, planner)
    assert spin_until(executor, lambda: answers.publisher.get_subscription_count() > 0)
    probe.send_goal()
    assert spin_until(executor, lambda: len(probe.demands) == 1, each=probe.publish_state)
    probe.send_goal()       # goal 1 is left unanswered: as if it never reached the controller
    assert spin_until(executor, lambda: len(probe.demands) == 2, each=probe.publish_state)
    second = demand_messages.demand_id_from_msg(probe.demands[1])
    answers.received(second)
    answers.answer(second, Answer.TAKEN, 'motion 1')
    assert spin_until(executor, lambda: probe.said(1, 'failed'), each=probe.publish_state)
    assert probe.said(1, 'failed')[0]['reason'] == 'superseded'
    assert probe.said(2, 'failed') == [] and probe.said(2, 'refused') == []
    assert spin_until(executor, lambda: planner.delivery.handshake.waiting() == 0)
    assert len(probe.demands) == 2


def handshake_alone(add, wait):
    """Return (handshake, ends): a ``DemandHandshake`` on a node of its own."""
    node = add(Node('handshake_alone'))
    ends = []
    handshake = DemandHandshake(node, CallbackGuard(node), node.get_logger(),
                                lambda pending, end, text: ends.append((pending.goal_id, end)),
                                lambda: wait)
    return handshake, ends


def test_a_demand_sent_before_any_reader_is_sent_again_when_one_matches(ros):
    """No timer: the writer's matched event sends an unanswered demand again."""
    executor, add = ros
    handshake, ends = handshake_alone(add, 60.0)
    assert handshake.matched() == (0, 0)
    handshake.send('g-1', demand_messages.make_demands(HOME[None], 'g-1'), None)
    reader = add(Node('late_reader'))
    got = []
    reader.create_subscription(Float32MultiArray, 'joint_demands', got.append, 10)
    assert spin_until(executor, lambda: got)
    assert demand_messages.demand_id_from_msg(got[0]) == 'g-1'
    assert ends == [] and handshake.waiting() == 1


def test_a_demand_nobody_answers_ends_no_controller(ros):
    """A reader, but no controller's answers on the graph for ``wait``: NO_CONTROLLER."""
    executor, add = ros
    handshake, ends = handshake_alone(add, 0.3)
    reader = add(Node('mute_reader'))
    reader.create_subscription(Float32MultiArray, 'joint_demands', lambda m: None, 10)
    assert spin_until(executor, lambda: handshake.matched()[0] == 1)
    handshake.send('g-2', demand_messages.make_demands(HOME[None], 'g-2'), None)
    assert spin_until(executor, lambda: ends)
    assert ends == [('g-2', HandshakeEnd.NO_CONTROLLER)] and handshake.waiting() == 0
