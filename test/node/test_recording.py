"""
The recorder on real rclpy, its file read back by an independent reader (rosbags).

One publisher per recorded topic, of the type the stack uses, sends a known number of messages;
the transient-local ones (status topics, /tf_static, /robot_description, contacts) send theirs
before the recorder starts, so their one message must come through the durability it matches.
rosbags (not the mcap libraries the recorder writes with) then must find every topic with its
type and count, deserialize the messages from the definitions embedded in the file, and agree
with metadata.yaml. A path that cannot be written is refused before anything is subscribed.
"""

import os

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from control_msgs.msg import JointJog  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PoseArray, PoseStamped, TransformStamped  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mover6_control.errors import InvalidInputError  # noqa: E402
from mover6_control.nodes.messages import conversions, demand_messages  # noqa: E402
from mover6_control.nodes.recorder.node import RecorderNode  # noqa: E402
from mover6_control.nodes.runtime.qos import LATCHED_QOS, STATUS_QOS  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_testing import wait_until  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402 - requirements/test.txt
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float32MultiArray, String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402
import yaml  # noqa: E402

LIMIT = 30.0      # [s] generous limit of every wait
NAMES = [f'joint{i}' for i in range(1, 7)]
# topic: (type name, class, QoS, count); the latched ones are published before the recorder.
VOLATILE = {
    '/joint_states': ('sensor_msgs/msg/JointState', JointState, 10, 40),
    '/JointJog': ('control_msgs/msg/JointJog', JointJog, 10, 30),
    '/joint_demands': ('std_msgs/msg/Float32MultiArray', Float32MultiArray, 10, 2),
    '/pose_goal': ('geometry_msgs/msg/PoseStamped', PoseStamped, 10, 2),
    '/path_goal': ('geometry_msgs/msg/PoseArray', PoseArray, 10, 1),
    '/tf': ('tf2_msgs/msg/TFMessage', TFMessage, 100, 20),
    '/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', DiagnosticArray, 10, 5),
}
LATCHED = {
    '/planner/status': ('diagnostic_msgs/msg/DiagnosticStatus', DiagnosticStatus, STATUS_QOS),
    '/controller/status': ('diagnostic_msgs/msg/DiagnosticStatus', DiagnosticStatus,
                           STATUS_QOS),
    '/sim_bridge/contacts': ('diagnostic_msgs/msg/DiagnosticStatus', DiagnosticStatus,
                             STATUS_QOS),
    '/tf_static': ('tf2_msgs/msg/TFMessage', TFMessage, LATCHED_QOS),
    '/robot_description': ('std_msgs/msg/String', String, LATCHED_QOS),
}


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module."""
    rclpy.init()
    yield
    rclpy.try_shutdown()


def message(topic, k):
    """Return the ``k``-th message of ``topic``."""
    if topic == '/joint_states':
        return conversions.make_joint_state(NAMES, [0.01 * k] * 6, [0.0] * 6)
    if topic == '/JointJog':
        return conversions.make_joint_jog(NAMES, [0.001 * k] * 6)
    if topic == '/joint_demands':
        return demand_messages.make_demands(np.full((3, 6), 0.1 * k), goal_id=str(k))
    if topic == '/pose_goal':
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.pose.position.x = 0.3 + 0.01 * k
        msg.pose.orientation.w = 1.0
        return msg
    if topic == '/path_goal':
        msg = PoseArray()
        msg.header.frame_id = 'base_link'
        msg.poses = [PoseStamped().pose, PoseStamped().pose]
        return msg
    if topic in ('/tf', '/tf_static'):
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = 'base_link', f'link{k % 6 + 1}'
        t.transform.rotation.w = 1.0
        return TFMessage(transforms=[t])
    if topic == '/diagnostics':
        return DiagnosticArray(status=[conversions.make_status('bus', 'OK', f'cycle {k}')])
    if topic == '/robot_description':
        return String(data='<robot name="CPRMover6"/>')
    return conversions.make_status(topic, 'OK', 'ready', {'state': 'idle'})


def test_every_topic_recorded_with_its_type_and_count(tmp_path):
    """The rosbags reader finds every topic with its type and count; every message decodes."""
    node = rclpy.create_node('recording_tester')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    pubs = {}
    for topic, (_, kind, qos, _) in VOLATILE.items():
        pubs[topic] = node.create_publisher(kind, topic, qos)
    for topic, (_, kind, qos) in LATCHED.items():
        pubs[topic] = node.create_publisher(kind, topic, qos)
        pubs[topic].publish(message(topic, 0))
    bag = tmp_path / 'run1'
    wanted = list(VOLATILE) + list(LATCHED) + ['/not_published']
    recorder = RecorderNode(parameter_overrides=[
        Parameter('path', value=str(bag)), Parameter('topics', value=' '.join(wanted))])
    executor.add_node(recorder)
    try:
        def spin(period):
            executor.spin_once(timeout_sec=period)
        assert wait_until(lambda: all(recorder.subscriptions_by_topic.get(t)
                                      for t in list(VOLATILE) + list(LATCHED)),
                          LIMIT, spin), recorder.subscriptions_by_topic
        assert wait_until(lambda: all(pubs[t].get_subscription_count() >= 1 for t in VOLATILE),
                          LIMIT, spin)
        for topic, (_, _, _, count) in VOLATILE.items():
            for k in range(count):
                pubs[topic].publish(message(topic, k))
        expected = {t: v[3] for t, v in VOLATILE.items()} | dict.fromkeys(LATCHED, 1)
        assert wait_until(lambda: {t: recorder.bag.topics.get(t, {}).get('count')
                                   for t in expected} == expected, LIMIT, spin), \
            {t: v['count'] for t, v in recorder.bag.topics.items()}
    finally:
        executor.remove_node(recorder)
        recorder.destroy_node()           # finishes the file and writes metadata.yaml
        executor.shutdown()
        node.destroy_node()

    assert sorted(os.listdir(bag)) == ['metadata.yaml', 'run1_0.mcap']
    types = {t: v[0] for t, v in VOLATILE.items()} | {t: v[0] for t, v in LATCHED.items()}
    with AnyReader([bag]) as reader:
        found = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert found == {t: (types[t], expected[t]) for t in types}
        decoded = {}
        for connection, _, raw in reader.messages():
            decoded.setdefault(connection.topic, []).append(
                reader.deserialize(raw, connection.msgtype))
    positions = [m.position.tolist() for m in decoded['/joint_states']]
    assert positions == [pytest.approx([0.01 * k] * 6) for k in range(40)]
    assert decoded['/joint_demands'][1].layout.dim[0].label.endswith('goal 1')
    assert decoded['/planner/status'][0].values[0].key == 'state'
    assert decoded['/robot_description'][0].data == '<robot name="CPRMover6"/>'
    with open(bag / 'metadata.yaml') as f:
        info = yaml.safe_load(f)['rosbag2_bagfile_information']
    assert info['storage_identifier'] == 'mcap'
    assert info['message_count'] == sum(expected.values())
    # The schema is the complete ros2msg definition (rosbag2's layout: the dependencies after
    # a line of 80 '=' and 'MSG: pkg/msg/Type').
    with open(bag / 'run1_0.mcap', 'rb') as f:
        mcap_reader = make_reader(f)
        assert mcap_reader.get_header().profile == 'ros2'
        summary = mcap_reader.get_summary()
    schema = next(s for s in summary.schemas.values() if s.name == 'tf2_msgs/msg/TFMessage')
    assert schema.encoding == 'ros2msg'
    assert '=' * 80 + '\nMSG: geometry_msgs/msg/TransformStamped\n' in schema.data.decode()


@pytest.mark.parametrize('case', ['missing_folder', 'exists', 'under_a_file', 'empty'])
def test_bad_path_refused_before_anything_starts(tmp_path, case):
    """A path that cannot be written refuses the node at once, with the reason."""
    (tmp_path / 'file').write_text('')
    path = {'missing_folder': tmp_path / 'no' / 'bag', 'exists': tmp_path,
            'under_a_file': tmp_path / 'file' / 'bag', 'empty': ' '}[case]
    reason = {'missing_folder': 'does not exist', 'exists': 'already exists',
              'under_a_file': 'is not a folder', 'empty': 'empty'}[case]
    with pytest.raises(InvalidInputError, match=reason):
        RecorderNode(parameter_overrides=[Parameter('path', value=str(path))])
    assert not (tmp_path / 'no').exists()
