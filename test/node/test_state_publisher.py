"""
The package's state publisher on real rclpy: /robot_description, /tf_static, /tf from joints.

The flange's transform, composed from the /tf messages link by link, must be the package's
forward kinematics (``kinematics.forward.fk`` of ``mover6()``) of the same joint state; the URDF
tree behind /tf is parsed independently of the ArmModel the planner uses.
"""

import os
import time

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from mover6_control.errors import InvalidInputError  # noqa: E402
from mover6_control.kinematics.arm import mover6  # noqa: E402
from mover6_control.kinematics.forward import fk  # noqa: E402
from mover6_control.kinematics.rotations import quaternion_to_matrix  # noqa: E402
from mover6_control.kinematics.urdf_tree import parse_urdf  # noqa: E402
from mover6_control.nodes.messages import conversions  # noqa: E402
from mover6_control.nodes.runtime.qos import LATCHED_QOS  # noqa: E402
from mover6_control.nodes.state_publisher.node import (  # noqa: E402
    shipped_description, StatePublisherNode)
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_testing import wait_until  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

NAMES = [f'joint{i}' for i in range(1, 7)]
LIMIT = 30.0      # [s] generous limit of every wait


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module."""
    rclpy.init()
    yield
    rclpy.try_shutdown()


class Harness:
    """The state publisher and a test node on one executor."""

    def __init__(self, **params):
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        self.publisher = StatePublisherNode(parameter_overrides=overrides)
        self.node = rclpy.create_node('state_publisher_tester')
        self.tf, self.static, self.description = [], [], []
        self.node.create_subscription(TFMessage, '/tf', self.tf.append, 100)
        self.node.create_subscription(TFMessage, '/tf_static', self.static.append, LATCHED_QOS)
        self.node.create_subscription(String, 'robot_description', self.description.append,
                                      LATCHED_QOS)
        self.joints = self.node.create_publisher(JointState, 'joint_states', 10)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.publisher)
        self.executor.add_node(self.node)

    def spin(self, period=0.02):
        """Spin once, at most ``period`` [s]."""
        self.executor.spin_once(timeout_sec=period)

    def close(self):
        """Destroy both nodes."""
        self.executor.shutdown()
        self.publisher.destroy_node()
        self.node.destroy_node()


@pytest.fixture
def harness():
    """Return a running harness; destroy it afterwards."""
    h = Harness()
    yield h
    h.close()


def transform_matrix(t):
    """Return the (4, 4) matrix of a ``geometry_msgs/Transform``."""
    T = np.eye(4)
    T[:3, :3] = quaternion_to_matrix([t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w])
    T[:3, 3] = [t.translation.x, t.translation.y, t.translation.z]
    return T


def chain(transforms, root, tip):
    """Compose ``T_root_tip`` from ``TransformStamped`` messages (child -> parent lookup)."""
    by_child = {t.child_frame_id: t for t in transforms}
    T = np.eye(4)
    frame = tip
    while frame != root:
        t = by_child[frame]        # a missing link fails here, with its name
        T = transform_matrix(t.transform) @ T
        frame = t.header.frame_id
    return T


def test_description_and_static_are_latched(harness):
    """A late reader gets the URDF the nodes use, and the (empty) fixed-joint list once."""
    assert wait_until(lambda: harness.description and harness.static, LIMIT, harness.spin)
    text = harness.description[-1].data
    assert text == shipped_description()
    assert '<robot name="CPRMover6">' in text
    # The Mover6 URDF has no fixed joint: /tf_static carries none (robot_state_publisher, too).
    assert harness.static[-1].transforms == []


@pytest.mark.parametrize('q', [[0.0] * 6, [0.3, -0.4, 0.9, 1.2, -0.7, 2.0],
                               [-1.5, 1.0, -1.2, -2.0, 1.3, -0.4]])
def test_flange_transform_is_forward_kinematics(harness, q):
    """base_link -> link6 composed from /tf equals fk of the same joint state."""
    stamp = conversions.seconds_to_stamp(1234.5)
    harness.tf.clear()

    def sent_and_seen():
        harness.joints.publish(conversions.make_joint_state(NAMES, q, stamp=stamp))
        return any(m.transforms and m.transforms[0].header.stamp == stamp for m in harness.tf)
    assert wait_until(sent_and_seen, LIMIT, harness.spin)
    msg = next(m for m in harness.tf if m.transforms[0].header.stamp == stamp)
    assert {t.child_frame_id for t in msg.transforms} == {f'link{i}' for i in range(1, 7)}
    T = chain(msg.transforms, 'base_link', 'link6')
    expected = fk(mover6(), np.array(q))
    np.testing.assert_allclose(T, expected, atol=1e-6)
    if q == [0.0] * 6:      # the flange at (0.345, 0, 0.4425) at home
        np.testing.assert_allclose(T[:3, 3], [0.345, 0.0, 0.4425], atol=1e-9)


def test_the_gripper_joint_places_its_finger(harness):
    """
    /joint_states as the sim bridge and the driver publish them (the arm and the gripper).

    The seventh name moves the URDF's gripper_finger along its axis; the arm's chain is the
    forward kinematics of its six joints, whatever else the message names.
    """
    q = [0.3, -0.4, 0.9, 1.2, -0.7, 2.0]
    stamp = conversions.seconds_to_stamp(99.0)
    harness.tf.clear()

    def sent_and_seen():
        harness.joints.publish(conversions.make_joint_state(NAMES + ['gripper'], q + [0.02],
                                                            stamp=stamp))
        return any(m.transforms and m.transforms[0].header.stamp == stamp for m in harness.tf)
    assert wait_until(sent_and_seen, LIMIT, harness.spin)
    msg = next(m for m in harness.tf if m.transforms[0].header.stamp == stamp)
    np.testing.assert_allclose(chain(msg.transforms, 'base_link', 'link6'),
                               fk(mover6(), np.array(q)), atol=1e-6)
    finger = chain(msg.transforms, 'link6', 'gripper_finger')
    np.testing.assert_allclose(finger[:3, 3], [0.0, 0.02, 0.03], atol=1e-9)   # axis y, at 0.03


def test_frame_prefix_and_partial_joint_states():
    """frame_prefix prefixes every frame; only the joints a message names are published."""
    h = Harness(frame_prefix='arm1/')
    try:
        msg = JointState(name=['joint2', 'joint3'], position=[0.2, 0.3])
        h.tf.clear()

        def seen():
            h.joints.publish(msg)
            return bool(h.tf)
        assert wait_until(seen, LIMIT, h.spin)
        frames = {(t.header.frame_id, t.child_frame_id) for t in h.tf[-1].transforms}
        assert frames == {('arm1/link1', 'arm1/link2'), ('arm1/link2', 'arm1/link3')}
    finally:
        h.close()


def tf_count_while_streaming(h, seconds):
    """Publish /joint_states every 10 ms for ``seconds`` [s] of wall time; return the /tf count."""
    msg = JointState(name=NAMES, position=[0.1] * 6)
    h.tf.clear()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        h.joints.publish(msg)
        h.spin(0.01)
    return len(h.tf)


def test_tf_at_most_publish_frequency_and_a_new_frequency_applies_at_once():
    """100 Hz of /joint_states give /tf at most publish_frequency a second; a set changes it."""
    h = Harness(publish_frequency=5.0)
    try:
        assert wait_until(lambda: tf_count_while_streaming(h, 0.1) > 0, LIMIT)
        slow = tf_count_while_streaming(h, 2.0)
        assert 1 <= slow <= 2.0 * 5.0 + 1, slow             # never more than the period allows
        result = h.publisher.set_parameters([Parameter('publish_frequency', value=50.0)])
        assert result[0].successful
        fast = tf_count_while_streaming(h, 2.0)
        assert fast > 2.0 * 5.0 + 1, fast                   # more than 5 Hz could have sent
        assert fast <= 2.0 * 50.0 + 1, fast
    finally:
        h.close()


def test_bad_description_refused():
    """A description that is no URDF tree stops the node with the reason."""
    with pytest.raises(InvalidInputError, match='not XML'):
        StatePublisherNode(parameter_overrides=[Parameter('robot_description', value='<robot')])
    two_roots = '<robot name="x"><link name="a"/><link name="b"/></robot>'
    with pytest.raises(InvalidInputError, match='one root link'):
        parse_urdf(two_roots)
