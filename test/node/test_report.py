"""
The report of a recording (``./run.sh report BAG``): motions rebuilt from what went over the wire.

A recording is written with the package's ``BagWriter`` from serialized messages of the types
the stack sends, with a known story: a linear goal that is planned, demanded and arrives (the
joint states move along the demand and settle 1 mrad short of it), then a refused goal. The
report must find both, with the controller's result, the planner's reason, the final errors of
the recorded joint states, and write the demo's files.
"""

from geometry_msgs.msg import PoseStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.recorder.bag_writer import BagWriter
from mover6_control.tools.report import make_report, read_recording
import numpy as np
import pytest
from rclpy.serialization import serialize_message

ARM = mover6()
NAMES = list(ARM.joint_names)
S = 10**9          # [ns] a second


def goal_msg(T):
    """Return a PoseStamped of ``T`` in base_link."""
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = conversions.matrix_to_pose(T)
    return msg


def write_story(path):
    """Write the recording of the module docstring; return the demanded waypoints."""
    bag = BagWriter(str(path))
    types = {'/joint_states': 'sensor_msgs/msg/JointState',
             '/pose_goal': 'geometry_msgs/msg/PoseStamped',
             '/joint_demands': 'std_msgs/msg/Float32MultiArray',
             '/planner/status': 'diagnostic_msgs/msg/DiagnosticStatus',
             '/controller/status': 'diagnostic_msgs/msg/DiagnosticStatus'}
    for topic, kind in types.items():
        bag.add_topic(topic, kind)

    def put(topic, msg, t):
        bag.write(topic, serialize_message(msg), int(t * S))

    Q = np.linspace(np.zeros(6), [0.2, 0.3, -0.2, 0.0, 0.1, 0.0], 5)
    T_goal = fk(ARM, Q[-1])
    t0 = 1000.0
    put('/pose_goal', goal_msg(T_goal), t0)
    put('/planner/status', conversions.make_status(
        'planner', 'OK', 'planned', {'result': 'planned', 'goal_id': '3'}), t0 + 0.1)
    put('/joint_demands', demand_messages.make_demands(Q, goal_id='3'), t0 + 0.11)
    q_end = Q[-1] - 0.001
    for k in range(101):                           # 100 Hz for 1 s, then held
        q = Q[0] + (q_end - Q[0]) * min(k / 80.0, 1.0)
        put('/joint_states', conversions.make_joint_state(NAMES, q, np.zeros(6)),
            t0 + 0.12 + 0.01 * k)
    put('/controller/status', conversions.make_status('controller', 'OK', 'executing', {
        'state': 'executing', 'goal_id': '3'}), t0 + 0.2)
    put('/controller/status', conversions.make_status('controller', 'OK', 'arrived', {
        'state': 'settling', 'goal_id': '3', 'result': 'arrived'}), t0 + 0.95)
    put('/controller/status', conversions.make_status('controller', 'OK', 'idle', {
        'state': 'idle', 'goal_id': '3', 'result': 'arrived'}), t0 + 1.0)
    far = np.eye(4)
    far[:3, 3] = (0.9, 0.0, 0.4)
    put('/pose_goal', goal_msg(far), t0 + 2.0)
    put('/planner/status', conversions.make_status(
        'planner', 'ERROR', 'goal refused (out_of_reach)',
        {'result': 'refused', 'reason': 'out_of_reach', 'goal_id': '4'}), t0 + 2.05)
    bag.close()
    return Q, q_end


def test_report_rebuilds_the_motions(tmp_path):
    """Both goals are found: the arrival with its figures, the refusal with its reason."""
    Q, q_end = write_story(tmp_path / 'story')
    topics, counts = read_recording(str(tmp_path / 'story'))
    assert counts == {'/joint_states': 101, '/pose_goal': 2, '/joint_demands': 1,
                      '/planner/status': 2, '/controller/status': 3}
    rows, files = make_report(str(tmp_path / 'story'), str(tmp_path / 'report'), ARM,
                              render=False, say=lambda text: None)
    assert [r['motion'] for r in rows] == ['01_pose_goal_linear', '02_pose_goal_linear']
    arrived, refused = rows
    assert arrived['result'] == 'arrived'
    assert arrived['final_joint_error'] == pytest.approx(0.001, abs=1e-6)
    assert arrived['final_position_error'] == pytest.approx(
        np.linalg.norm(fk(ARM, q_end)[:3, 3] - fk(ARM, Q[-1])[:3, 3]), abs=1e-6)
    assert arrived['duration'] == pytest.approx(1.0, abs=1e-6)   # the goal to the hold
    assert len(arrived['planned_path']) == len(Q)
    assert refused == {'motion': '02_pose_goal_linear', 'goal': refused['goal'],
                       'result': 'refused', 'reason': 'out_of_reach',
                       'message': 'goal refused (out_of_reach)'}
    assert refused['goal'].startswith('0.9000 0.0000 0.4000')
    names = {p.rsplit('/', 1)[-1] for p in files}
    assert {'01_pose_goal_linear_path3d.png', '01_pose_goal_linear_joints.png',
            'metrics.md', 'metrics.json'} <= names
    assert '| 02_pose_goal_linear |' in (tmp_path / 'report' / 'metrics.md').read_text()
