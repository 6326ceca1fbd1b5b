"""
The planner node in one process with real rclpy: plans, refusals, and what it publishes.

A probe node publishes /joint_states and goals and listens to /joint_demands and
/planner/status, as a user's nodes would.
"""

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.controller.demand_answers import DemandAnswers
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.messages.demand_acks import Answer
from mover6_control.nodes.planner.node import PlannerNode
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from ros_testing import spin_until
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray, Header

pytestmark = pytest.mark.node
ARM = mover6()
HOME = np.zeros(6)
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)


class Probe(Node):
    """Publishes what the planner consumes, records what it produces."""

    def __init__(self):
        super().__init__('planner_probe')
        self.demands = []
        self.statuses = []
        self.state_pub = self.create_publisher(JointState, 'joint_states', 10)
        self.pose_pub = self.create_publisher(PoseStamped, 'pose_goal', 10)
        self.path_pub = self.create_publisher(PoseArray, 'path_goal', 10)
        self.demands_sub = self.create_subscription(Float32MultiArray, 'joint_demands',
                                                    lambda m: self.demands.append(m), 10)
        # The controller's answers, given by the tests that answer (the controller's part).
        self.answers = DemandAnswers(self, lambda: self.get_clock().now().nanoseconds)
        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(DiagnosticStatus, 'planner/status',
                                 lambda m: self.statuses.append(m), qos)

    def publish_state(self, q):
        """Publish one /joint_states message at ``q``."""
        self.state_pub.publish(conversions.make_joint_state(ARM.joint_names, q, np.zeros(6)))


@pytest.fixture
def nodes():
    """Return (executor, planner, probe) with both nodes spinning on one executor."""
    rclpy.init()
    planner = PlannerNode()
    probe = Probe()
    executor = SingleThreadedExecutor()
    executor.add_node(planner)
    executor.add_node(probe)
    yield executor, planner, probe
    executor.shutdown()
    planner.destroy_node()
    probe.destroy_node()
    rclpy.try_shutdown()


def connected(executor, probe):
    """Wait until the probe's publishers reach the planner's subscriptions."""
    assert spin_until(executor, lambda: probe.pose_pub.get_subscription_count() > 0
                      and probe.state_pub.get_subscription_count() > 0
                      and probe.path_pub.get_subscription_count() > 0)
    assert spin_until(executor, lambda: len(probe.statuses) >= 1)


def goal_before_states(executor, probe):
    """Publish GOAL before any joint states; once it says it waits, return its first status."""
    connected(executor, probe)
    n = len(probe.statuses)
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = conversions.matrix_to_pose(GOAL)
    probe.pose_pub.publish(msg)
    assert spin_until(executor, lambda: any(
        conversions.status_values(m).get('result') == 'waiting_for_states'
        for m in probe.statuses[n:]))
    return n


ANSWERS = ('planned', 'refused', 'failed')


def answer(executor, probe, n, timeout=30.0):
    """Wait for the planner's answer about a goal (after status ``n``); return that status."""
    def answers():
        return [m for m in probe.statuses[n:]
                if conversions.status_values(m).get('result') in ANSWERS]
    assert spin_until(executor, lambda: answers(), timeout), 'planner did not answer'
    return answers()[0]


def send_pose(executor, probe, T, frame='base_link', quat=None, pub=None):
    """Publish a /pose_goal (or on ``pub``) and wait for the planner's answer; return it."""
    n = len(probe.statuses)
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose = conversions.matrix_to_pose(T)
    if quat is not None:
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = quat
    (pub or probe.pose_pub).publish(msg)
    return answer(executor, probe, n)


def give_state(executor, planner, probe, q):
    """Publish joint states until the planner holds them."""
    assert spin_until(executor, lambda: (probe.publish_state(q), planner.states.q is not None)[1]
                      and np.allclose(planner.states.q, q))


def test_reachable_goal_publishes_layout_and_ok(nodes):
    """A reachable goal: N x 6 with the layout on /joint_demands, OK with figures."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.OK, status.message
    assert spin_until(executor, lambda: len(probe.demands) == 1)
    msg = probe.demands[0]
    values = conversions.status_values(status)
    # The first dimension names the goal the demand is for, as the status does.
    assert values['goal_id'] == '0.000000000-1'
    assert [d.label for d in msg.layout.dim] == ['waypoints goal 0.000000000-1', 'joints']
    assert demand_messages.demand_id_from_msg(msg) == values['goal_id']
    Q = demand_messages.demands_from_msg(msg)
    # 20 path poses, plus the wrist turn that leaves the singular home pose.
    assert int(values['waypoints']) == Q.shape[0] >= 20
    assert float(values['path_length']) > 0.0 and float(values['predicted_duration']) > 0.0
    # Starts at the current configuration, ends at the goal pose (float32 on the wire).
    assert np.abs(Q[0] - HOME).max() < 1e-6
    assert np.linalg.norm(fk(ARM, Q[-1])[:3, 3] - GOAL[:3, 3]) < 1e-3
    assert ARM.within_limits(Q.max(axis=0)) and ARM.within_limits(Q.min(axis=0))


def refused(executor, probe, status, reason):
    """Assert an ERROR status with ``reason`` and nothing on /joint_demands."""
    assert status.level == DiagnosticStatus.ERROR, status.message
    values = conversions.status_values(status)
    assert values['result'] == 'refused'
    assert values['reason'] == reason, status.message
    spin_until(executor, lambda: len(probe.demands) > 0, timeout=0.5)
    assert probe.demands == []


def test_goal_before_any_joint_states_is_refused_after_the_wait(nodes):
    """No /joint_states within state_wait_timeout: the pose is unknown, the goal refused."""
    executor, planner, probe = nodes
    planner.set_parameters([Parameter('state_wait_timeout', value=0.5)])
    connected(executor, probe)
    assert conversions.status_values(probe.statuses[-1])['state'] == 'waiting_for_states'
    status = send_pose(executor, probe, GOAL)
    refused(executor, probe, status, 'no_joint_states')
    assert 'no valid /joint_states within 0.5 s' in status.message
    assert conversions.status_values(status)['state'] == 'waiting_for_states'


def test_goal_before_any_joint_states_waits_for_them_and_is_planned(nodes):
    """Issue 21: a goal that comes before the first states waits for them, then is planned."""
    executor, planner, probe = nodes
    # The goal says it waits (and for how long at most), and nothing is planned yet.
    n = goal_before_states(executor, probe)
    waiting = [conversions.status_values(m) for m in probe.statuses[n:]
               if conversions.status_values(m).get('result') == 'waiting_for_states'][0]
    assert waiting['wait_timeout'] == '5' and waiting['goal_id'] == '0.000000000-1'
    assert probe.demands == []
    probe.publish_state(HOME)
    status = answer(executor, probe, n)
    assert status.level == DiagnosticStatus.OK, status.message
    values = conversions.status_values(status)
    assert values['result'] == 'planned' and values['state'] == 'ready'
    assert values['goal_id'] == '0.000000000-1'
    assert spin_until(executor, lambda: len(probe.demands) >= 1)
    Q = demand_messages.demands_from_msg(probe.demands[0])
    assert np.abs(Q[0] - HOME).max() < 1e-6
    assert np.linalg.norm(fk(ARM, Q[-1])[:3, 3] - GOAL[:3, 3]) < 1e-3
    # The planner said it became ready in between.
    assert 'ready' in [conversions.status_values(m).get('state') for m in probe.statuses[n:]]


def test_unreachable_goal_is_refused_with_closest_pose(nodes):
    """Far outside the workspace: out_of_reach, with the errors of the closest pose found."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, pose_from_xyzabc(0.9, 0.0, 0.4, 0.0, np.pi / 2, 0.0))
    refused(executor, probe, status, 'out_of_reach')


def test_goal_beyond_joint_limits_is_refused(nodes):
    """A pose the arm reaches only with a joint past its +-90 deg limit: joint_limits."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    # Behind the base: joint 1 would have to turn past +-pi/2.
    q_behind = np.array([2.6, 0.2, 0.3, 0.0, 0.5, 0.0])
    T = fk(ARM.with_limits(lower=-np.pi * np.ones(6), upper=np.pi * np.ones(6)), q_behind)
    planner.set_parameters([Parameter('motion', value='joint')])
    status = send_pose(executor, probe, T)
    refused(executor, probe, status, 'joint_limits')


def test_wrong_frame_is_refused(nodes):
    """A goal in another frame (no TF lookup here) is refused with its frame named."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL, frame='world')
    refused(executor, probe, status, 'invalid_goal')
    assert '"world"' in status.message


@pytest.mark.parametrize('quat', [(0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, float('nan')),
                                  (0.5, 0.5, 0.5, 0.0)])
def test_malformed_quaternion_is_refused(nodes, quat):
    """A zero, non-finite or non-unit quaternion is refused; the node keeps running."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL, quat=quat)
    refused(executor, probe, status, 'invalid_goal')
    assert 'quaternion' in status.message
    # Still alive and planning.
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.OK, status.message


def test_path_goal_spline_and_arc(nodes):
    """A /path_goal through via poses plans for both path shapes."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    goal = pose_from_xyzabc(0.28, 0.10, 0.36, 0.0, np.pi / 2, 0.0)
    for shape in ('spline', 'arc'):
        planner.set_parameters([Parameter('path_motion', value=shape)])
        n = len(probe.statuses)
        msg = PoseArray()
        msg.header.frame_id = 'base_link'
        msg.poses = [conversions.matrix_to_pose(T) for T in (via, goal)]
        count = len(probe.demands)
        probe.path_pub.publish(msg)
        status = answer(executor, probe, n)
        assert status.level == DiagnosticStatus.OK, f'{shape}: {status.message}'
        assert spin_until(executor, lambda: len(probe.demands) > count)
        Q = demand_messages.demands_from_msg(probe.demands[-1])
        assert np.linalg.norm(fk(ARM, Q[-1])[:3, 3] - goal[:3, 3]) < 1e-3


def test_plan_with_nobody_listening_is_refused(nodes):
    """No reader on /joint_demands (no controller): refused after match_timeout, said why."""
    executor, planner, probe = nodes
    probe.destroy_subscription(probe.demands_sub)
    planner.set_parameters([Parameter('match_timeout', value=0.5)])
    connected(executor, probe)
    publisher = planner.delivery.handshake.publisher
    assert spin_until(executor, lambda: publisher.get_subscription_count() == 0)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.ERROR, status.message
    assert conversions.status_values(status)['reason'] == 'no_controller'
    assert 'controller' in status.message


def set_remotely(executor, client, name, value):
    """Set one planner parameter through its parameter service; return the SetParametersResult."""
    future = client.set_parameters([Parameter(name, value=value)])
    assert spin_until(executor, future.done), f'setting {name} not answered'
    return future.result().results[0]


def test_parameter_service_refuses_bad_values_and_describes_ranges(nodes):
    """
    Parameter services: a bad value is refused with a reason and changes nothing.

    As ``ros2 param set`` would set it; and the descriptors carry the ranges and allowed values,
    as ``ros2 param describe`` shows them.
    """
    from rclpy.parameter_client import AsyncParameterClient
    executor, planner, probe = nodes
    client = AsyncParameterClient(probe, 'planner')
    assert spin_until(executor, lambda: client.services_are_ready())
    for name, value, words in (('motion', 'banana', 'one of: linear, parabolic, joint'),
                               ('n_waypoints', 1, 'n_waypoints'),
                               ('max_step', 'far', 'type'),
                               ('limit_set', 'hardware', 'read-only')):
        result = set_remotely(executor, client, name, value)
        assert not result.successful, name
        assert words in result.reason, result.reason
    assert planner.get_parameter('motion').value == 'linear'
    assert planner.get_parameter('n_waypoints').value == 20
    assert planner.get_parameter('max_step').value == 0.0
    assert planner.get_parameter('limit_set').value == 'within_90_deg'

    future = client.describe_parameters(['motion', 'n_waypoints', 'max_step', 'limit_set'])
    assert spin_until(executor, future.done)
    motion, n_waypoints, max_step, limit_set = future.result().descriptors
    assert motion.additional_constraints == 'one of: linear, parabolic, joint'
    assert 'shape' in motion.description
    assert (n_waypoints.integer_range[0].from_value, n_waypoints.integer_range[0].to_value) \
        == (2, 10000)
    assert max_step.floating_point_range[0].from_value == 0.0
    assert max_step.description.endswith('[m]')
    assert limit_set.read_only and 'within_90_deg' in limit_set.additional_constraints

    assert set_remotely(executor, client, 'motion', 'joint').successful   # a good one is taken
    assert planner.get_parameter('motion').value == 'joint'


def test_bad_start_parameters_stop_the_planner():
    """A value refused at run time is refused at start too, saying why."""
    rclpy.init()
    try:
        with pytest.raises(ValueError, match='one of: linear'):
            PlannerNode(parameter_overrides=[Parameter('motion', value='banana')])
    finally:
        rclpy.try_shutdown()


def as_controller(probe):
    """Return the probe's ``DemandAnswers`` (the controller's part) that answer as it does."""
    return probe.answers


def test_an_unanswered_demand_fails_once_no_controller_answers(nodes):
    """A reader of /joint_demands but no controller answering: failed, not_acknowledged."""
    executor, planner, probe = nodes
    probe.destroy_publisher(probe.answers.publisher)        # no controller on the graph
    planner.set_parameters([Parameter('match_timeout', value=0.5)])
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    goal_id = conversions.status_values(status)['goal_id']
    assert spin_until(executor, lambda: conversions.status_values(
        probe.statuses[-1]).get('result') == 'failed', 10.0)
    status = probe.statuses[-1]
    values = conversions.status_values(status)
    assert values['goal_id'] == goal_id and values['reason'] == 'not_acknowledged'
    assert status.level == DiagnosticStatus.ERROR
    assert 'no controller answers' in status.message
    assert [demand_messages.demand_id_from_msg(m) for m in probe.demands] == [goal_id]
    assert planner.delivery.handshake.waiting() == 0


def test_a_taken_demand_ends_its_handshake(nodes):
    """The controller's answers say received, then taken: the goal waits for nothing more."""
    executor, planner, probe = nodes
    answers = as_controller(probe)
    connected(executor, probe)
    assert spin_until(executor, lambda: answers.publisher.get_subscription_count() > 0)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    goal_id = conversions.status_values(status)['goal_id']
    assert spin_until(executor, lambda: len(probe.demands) == 1)
    assert planner.delivery.handshake.waiting() == 1
    answers.received(goal_id)
    answers.answer(goal_id, Answer.TAKEN, 'motion 1')
    assert spin_until(executor, lambda: planner.delivery.handshake.waiting() == 0)
    assert conversions.status_values(probe.statuses[-1])['result'] == 'planned'


def test_malformed_latest_joint_states_refuse_the_goal_until_good_ones_come(nodes):
    """
    The latest /joint_states is what a goal plans from: malformed, the goal is refused.

    The planner keeps the latest message unconverted (100 a second only need keeping) and
    converts it when a goal comes; a malformed one leaves the pose unknown: the goal waits for
    valid states (state_wait_timeout), then is refused with what was wrong.
    """
    executor, planner, probe = nodes
    planner.set_parameters([Parameter('state_wait_timeout', value=0.5)])
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    bad = conversions.make_joint_state(ARM.joint_names[:5], HOME[:5], np.zeros(5))
    assert spin_until(executor,
                      lambda: (probe.state_pub.publish(bad), planner.states.q is None)[1])
    status = send_pose(executor, probe, GOAL)
    refused(executor, probe, status, 'no_joint_states')
    assert 'malformed' in status.message and 'joint6' in status.message, status.message
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.OK, status.message


def send_path_to(executor, probe, topic, poses, frame='base_link'):
    """Publish a PoseArray on ``topic`` and wait for the planner's answer; return the status."""
    pub = probe.create_publisher(PoseArray, topic, 10)
    assert spin_until(executor, lambda: pub.get_subscription_count() > 0)
    n = len(probe.statuses)
    msg = PoseArray()
    msg.header.frame_id = frame
    msg.poses = [conversions.matrix_to_pose(T) for T in poses]
    pub.publish(msg)
    return answer(executor, probe, n)


def only_these_sent(executor, probe, goal_ids):
    """
    Assert that no demand but those of ``goal_ids`` was sent, without a fixed wait.

    A valid goal after them is the marker: its demand comes after any the planner sent before
    it (one publisher, one topic, in order), so once it is here nothing else can still come.
    """
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.OK, status.message
    marker = conversions.status_values(status)['goal_id']

    def sent():
        return {demand_messages.demand_id_from_msg(m) for m in probe.demands}
    assert spin_until(executor, lambda: marker in sent())
    assert sent() == set(goal_ids) | {marker}


def test_path_goal_joint_plans_the_via_point_polynomial(nodes):
    """/path_goal/joint [via, goal]: a joint move through the via pose, timed as announced."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    goal = pose_from_xyzabc(0.28, 0.10, 0.36, 0.0, np.pi / 2, 0.0)
    status = send_path_to(executor, probe, 'path_goal/joint', (via, goal))
    assert status.level == DiagnosticStatus.OK, status.message
    values = conversions.status_values(status)
    assert values['motion'] == 'joint' and 'profile' not in values
    assert spin_until(executor, lambda: len(probe.demands) >= 1)
    Q = demand_messages.demands_from_msg(probe.demands[-1])
    assert demand_messages.demand_profile_from_msg(probe.demands[-1]) == ''
    assert np.abs(Q[0] - HOME).max() < 1e-6
    assert min(np.linalg.norm(fk(ARM, q)[:3, 3] - via[:3, 3]) for q in Q) < 1e-4
    assert np.linalg.norm(fk(ARM, Q[-1])[:3, 3] - goal[:3, 3]) < 1e-3
    # Two via poses are not this shape's: refused, nothing sent for it (the first goal's
    # demand may be sent again: no controller acknowledges it here).
    status = send_path_to(executor, probe, 'path_goal/joint', (via, via, goal))
    assert status.level == DiagnosticStatus.ERROR and 'exactly one via pose' in status.message
    assert conversions.status_values(status)['reason'] == 'invalid_goal'
    only_these_sent(executor, probe, {values['goal_id']})


def test_a_goals_profile_is_forwarded_with_its_demand(nodes):
    """Frame id 'base_link profile quintic': the demand asks for it, the parameter stays."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL, frame='base_link profile quintic')
    assert status.level == DiagnosticStatus.OK, status.message
    values = conversions.status_values(status)
    assert values['profile'] == 'quintic'
    assert spin_until(executor, lambda: len(probe.demands) >= 1)
    msg = probe.demands[-1]
    assert msg.layout.dim[0].label == f'waypoints goal {values["goal_id"]} profile quintic'
    assert planner.get_parameter('profile').value == 'continuous'
    # An unknown profile is refused before anything is sent for it.
    status = send_pose(executor, probe, GOAL, frame='base_link profile banana')
    assert status.level == DiagnosticStatus.ERROR and 'banana' in status.message
    assert conversions.status_values(status)['reason'] == 'invalid_goal'
    only_these_sent(executor, probe, {values['goal_id']})


def test_goal_into_the_table_is_refused_for_a_collision_and_the_switch_applies_live(nodes):
    """The issue's table goal: refused, naming the tool, the table, the depth; off: planned."""
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    T = fk(ARM, HOME)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]) @ T[:3, :3]
    T[:3, 3] = (0.25, 0.0, 0.0)                # flange pointing down at the table surface
    status = send_pose(executor, probe, T)
    refused(executor, probe, status, 'collision')
    assert 'link6 tool is 100 mm into the table margin' in status.message
    values = conversions.status_values(status)
    assert values['shapes'] == 'link6 tool and table'
    planner.set_parameters([Parameter('collision_check', value=False)])
    status = send_pose(executor, probe, T)
    assert status.level == DiagnosticStatus.OK, status.message


def table_goal(z=-0.05):
    """Return the issue's table goal: the flange pointing down, ``z`` [m] below the table top."""
    T = fk(ARM, HOME)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]) @ T[:3, :3]
    T[:3, 3] = (0.25, 0.0, z)
    return T


def goal_topics(planner):
    """Return {topic: message type} of every goal the planner takes: its subscriptions."""
    return {sub.topic_name: sub.msg_type for sub in planner.subscriptions
            if sub.msg_type in (PoseStamped, PoseArray)}


def test_every_goal_topic_refuses_the_table_goal_for_a_collision(nodes):
    """Issue 24 (4): each goal topic the planner subscribes checks the goal for collisions."""
    executor, planner, probe = nodes
    topics = goal_topics(planner)
    # The shapes of both kinds, /path_goal/joint among them (it skipped the check).
    assert {'/pose_goal', '/path_goal', '/pose_goal/joint', '/path_goal/joint'} <= set(topics)
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    T = table_goal()
    for topic, msg_type in sorted(topics.items()):
        if msg_type is PoseStamped:
            pub = probe.create_publisher(PoseStamped, topic, 10)
            assert spin_until(executor, lambda: pub.get_subscription_count() > 0)
            status = send_pose(executor, probe, T, pub=pub)
        else:
            status = send_path_to(executor, probe, topic, (via, T))
        values = conversions.status_values(status)
        assert status.level == DiagnosticStatus.ERROR, f'{topic}: {status.message}'
        assert values['reason'] == 'collision', f'{topic}: {status.message}'
        assert 'link6 tool is 150 mm into the table margin' in status.message, topic
    spin_until(executor, lambda: len(probe.demands) > 0, timeout=0.5)
    assert probe.demands == []


def pose_array(poses, frame='base_link'):
    """Return a PoseArray of ``poses`` (k, 4, 4)."""
    msg = PoseArray()
    msg.header.frame_id = frame
    msg.poses = [conversions.matrix_to_pose(T) for T in poses]
    return msg


def test_huge_path_goals_are_refused_for_their_count_first(nodes):
    """
    Issue 24 (6): 10,000-pose arc and parabolic goals are refused for their via count.

    Before any pose is converted or solved: one bad quaternion among them is never reached
    (it was, after half a minute of reachability checks of the via poses).
    """
    executor, planner, probe = nodes
    connected(executor, probe)
    give_state(executor, planner, probe, HOME)
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    goal = pose_from_xyzabc(0.28, 0.10, 0.36, 0.0, np.pi / 2, 0.0)
    msg = pose_array([via] * 9999 + [goal])
    msg.poses[5000].orientation.w = 0.0     # not a unit quaternion: converting would refuse it
    msg.poses[5000].orientation.y = 0.0
    for shape in ('arc', 'parabolic', 'joint'):
        pub = probe.create_publisher(PoseArray, f'path_goal/{shape}', 10)
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0)
        n = len(probe.statuses)
        pub.publish(msg)
        status = answer(executor, probe, n)
        assert status.level == DiagnosticStatus.ERROR, status.message
        assert f'{shape} needs exactly one via pose, got 9999' in status.message
    status = send_path_to(executor, probe, 'path_goal/spline', [via] * 200 + [goal])
    assert 'at most 100 via poses, got 200' in status.message
    spin_until(executor, lambda: len(probe.demands) > 0, timeout=0.5)
    assert probe.demands == []


def call_stop(executor, probe):
    """Call the planner's ~/stop service; return its response."""
    from std_srvs.srv import Trigger
    client = probe.create_client(Trigger, 'planner/stop')
    assert spin_until(executor, client.service_is_ready)
    future = client.call_async(Trigger.Request())
    assert spin_until(executor, future.done), 'the planner did not answer ~/stop'
    return future.result()


def test_planner_answers_goals_and_stop_while_a_goal_is_pending(nodes):
    """
    A goal waiting in the planning thread holds up neither other answers nor ~/stop.

    The waiting goal (no states yet) is dropped by the stop: refused 'stopped', and no demand
    goes out for it when the states come.
    """
    executor, planner, probe = nodes
    planner.set_parameters([Parameter('state_wait_timeout', value=60.0)])
    n = goal_before_states(executor, probe)
    # A malformed goal meanwhile: refused at once, while the first one still waits.
    status = send_path_to(executor, probe, 'path_goal/arc', [GOAL] * 10000)
    assert 'arc needs exactly one via pose' in status.message
    assert conversions.status_values(status)['goal_seq'] == '2'
    assert not [m for m in probe.statuses[n:]
                if conversions.status_values(m).get('goal_seq') == '1'
                and conversions.status_values(m).get('result') in ANSWERS]
    response = call_stop(executor, probe)
    assert response.success and 'dropped' in response.message

    def first_goal_answers():
        return [m for m in probe.statuses[n:]
                if conversions.status_values(m).get('goal_seq') == '1'
                and conversions.status_values(m).get('result') in ANSWERS]
    assert spin_until(executor, first_goal_answers)
    status = first_goal_answers()[0]
    assert conversions.status_values(status)['reason'] == 'stopped', status.message
    give_state(executor, planner, probe, HOME)
    spin_until(executor, lambda: len(probe.demands) > 0, timeout=1.0)
    assert probe.demands == []
    # A goal after the stop is planned as usual (fresh states: those above are a second old).
    give_state(executor, planner, probe, HOME)
    status = send_pose(executor, probe, GOAL)
    assert status.level == DiagnosticStatus.OK, status.message


@pytest.mark.parametrize('answer, reason', [(Answer.REFUSED, 'controller_refused'),
                                            (Answer.NOT_READY, 'controller_not_ready')])
def test_a_demand_the_controller_refuses_ends_the_goal_on_the_planners_status(
        nodes, answer, reason):
    """
    Issue 21: the controller refuses the demand: the planner says so, with the reason.

    Refused for itself (``controller_refused``) or for the controller's state
    (``controller_not_ready``); the handshake has ended: nothing waits for that goal.
    """
    executor, planner, probe = nodes
    answers = as_controller(probe)
    connected(executor, probe)
    assert spin_until(executor, lambda: answers.publisher.get_subscription_count() > 0)
    give_state(executor, planner, probe, HOME)
    n = len(probe.statuses)
    status = send_pose(executor, probe, GOAL)
    assert conversions.status_values(status)['result'] == 'planned'
    goal_id = conversions.status_values(status)['goal_id']
    assert spin_until(executor, lambda: len(probe.demands) == 1)
    text = 'cannot take a demand while waiting_for_states: waiting for /joint_states'
    answers.received(goal_id)
    answers.answer(goal_id, answer, text)
    assert spin_until(executor, lambda: conversions.status_values(
        probe.statuses[-1]).get('reason') == reason)
    status = probe.statuses[-1]
    values = conversions.status_values(status)
    assert status.level == DiagnosticStatus.ERROR and values['result'] == 'refused'
    assert values['goal_id'] == goal_id and text in status.message
    assert len(probe.statuses) > n
    assert planner.delivery.handshake.waiting() == 0
    assert len(probe.demands) == 1


def goal_answers(statuses, goal_id):
    """Return the results the planner's status said for ``goal_id``, in order."""
    return [conversions.status_values(m).get('result') for m in statuses
            if conversions.status_values(m).get('goal_id') == goal_id
            and conversions.status_values(m).get('result') in ANSWERS]


def test_a_refusal_as_soon_as_the_demand_arrives_comes_after_planned(nodes):
    """
    The demand goes out before the duration is predicted; the status keeps its order.

    The controller refuses a 1000-waypoint demand the moment it arrives, and a ~/stop comes the
    moment the next one arrives (while the planner may still predict the duration): each goal
    is 'planned' with its predicted duration, then refused (controller_refused, stopped).
    """
    executor, planner, probe = nodes
    planner.set_parameters([Parameter('n_waypoints', value=1000)])
    answers = as_controller(probe)
    from std_srvs.srv import Trigger
    stop = probe.create_client(Trigger, 'planner/stop')
    connected(executor, probe)
    assert spin_until(executor, lambda: answers.publisher.get_subscription_count() > 0)
    assert spin_until(executor, stop.service_is_ready)
    # 'planned' and the refusal can come back to back: a queue deep enough for both (the
    # probe's own keeps the last status only).
    statuses = []
    probe.create_subscription(DiagnosticStatus, 'planner/status', statuses.append, QoSProfile(
        depth=50, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    reason = 'cannot take a demand while waiting_for_states: waiting for /joint_states'
    calls = []

    def on_demand(msg):
        goal_id = demand_messages.demand_id_from_msg(msg)
        if goal_id in calls:
            return                              # sent again: answered already
        if not calls:
            answers.received(goal_id)
            answers.answer(goal_id, Answer.REFUSED, reason)
        elif len(calls) == 1:
            stop.call_async(Trigger.Request())
        calls.append(goal_id)
    probe.create_subscription(Float32MultiArray, 'joint_demands', on_demand, 10)
    for expected in ('controller_refused', 'stopped'):
        give_state(executor, planner, probe, HOME)
        n = len(calls)
        probe.pose_pub.publish(PoseStamped(header=Header(frame_id='base_link'),
                                           pose=conversions.matrix_to_pose(GOAL)))
        assert spin_until(executor, lambda: len(calls) > n, 30.0)
        goal_id = calls[n]
        assert spin_until(executor, lambda: len(goal_answers(statuses, goal_id)) == 2, 30.0)
        assert goal_answers(statuses, goal_id) == ['planned', 'refused']
        said = [conversions.status_values(m) for m in statuses
                if conversions.status_values(m).get('goal_id') == goal_id]
        planned = next(v for v in said if v.get('result') == 'planned')
        assert int(planned['waypoints']) >= 1000
        assert float(planned['predicted_duration']) > 0.0
        assert [v['reason'] for v in said if v.get('result') == 'refused'] == [expected]
