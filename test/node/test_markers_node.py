"""
The markers node on real rclpy: table, keep-out boxes, the goal and the planned tool path.

The path's points must be the forward kinematics of the demanded waypoints; the keep-out boxes
follow the planner's parameter (read at start, then through /parameter_events).
"""

import os

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from geometry_msgs.msg import PoseStamped  # noqa: E402
from mover6_control.kinematics.arm import mover6  # noqa: E402
from mover6_control.kinematics.forward import fk_batch  # noqa: E402
from mover6_control.nodes.markers.node import MarkersNode  # noqa: E402
from mover6_control.nodes.messages import conversions, demand_messages  # noqa: E402
from mover6_control.nodes.runtime.qos import LATCHED_QOS  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_testing import wait_until  # noqa: E402
from std_msgs.msg import Float32MultiArray  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

LIMIT = 30.0      # [s] generous limit of every wait
BOX = [0.3, -0.1, 0.0, 0.4, 0.1, 0.2]


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module."""
    rclpy.init()
    yield
    rclpy.try_shutdown()


class Harness:
    """The markers node, a stand-in planner (its parameters only) and a test node."""

    def __init__(self, planner_boxes=None, **params):
        self.nodes = []
        if planner_boxes is not None:
            self.planner = rclpy.create_node('planner', parameter_overrides=[
                Parameter('keep_out_boxes', value=planner_boxes),
                Parameter('table_margin', value=0.05)],
                automatically_declare_parameters_from_overrides=True)
            self.nodes.append(self.planner)
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        self.markers = MarkersNode(parameter_overrides=overrides)
        self.node = rclpy.create_node('markers_tester')
        self.received = []
        self.node.create_subscription(MarkerArray, 'markers', self.received.append, LATCHED_QOS)
        self.goal = self.node.create_publisher(PoseStamped, 'pose_goal', 10)
        self.demands = self.node.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.nodes += [self.markers, self.node]
        self.executor = SingleThreadedExecutor()
        for node in self.nodes:
            self.executor.add_node(node)

    def spin(self, period=0.02):
        """Spin once, at most ``period`` [s]."""
        self.executor.spin_once(timeout_sec=period)

    def latest(self, ns):
        """Return the latest markers of namespace ``ns`` (ADD only)."""
        if not self.received:
            return []
        return [m for m in self.received[-1].markers if m.ns == ns and m.action == Marker.ADD]

    def close(self):
        """Destroy the nodes."""
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()


def test_table_keep_out_goal_and_path():
    """Own keep-out boxes; a pose goal's axes; the planned path is fk of the demands."""
    h = Harness(planner_node='', keep_out_boxes=BOX)
    try:
        assert wait_until(lambda: h.latest('keep_out'), LIMIT, h.spin)
        assert h.received[-1].markers[0].action == Marker.DELETEALL
        box = h.latest('keep_out')[0]
        np.testing.assert_allclose([box.pose.position.x, box.pose.position.y,
                                    box.pose.position.z], [0.35, 0.0, 0.1])
        np.testing.assert_allclose([box.scale.x, box.scale.y, box.scale.z], [0.1, 0.2, 0.2])
        assert {m.header.frame_id for m in h.received[-1].markers} == {'base_link'}
        assert len(h.latest('table')) == 2          # the slab and the 2 cm margin above it

        goal = PoseStamped()
        goal.header.frame_id = 'base_link'
        goal.pose = conversions.matrix_to_pose(
            np.array([[0, 0, 1, 0.3], [0, 1, 0, 0.05], [-1, 0, 0, 0.36], [0, 0, 0, 1.0]]))
        assert wait_until(lambda: h.goal.publish(goal) or h.latest('goal'), LIMIT, h.spin)
        z_axis = h.latest('goal')[2]
        start, end = z_axis.points
        np.testing.assert_allclose([start.x, start.y, start.z], [0.3, 0.05, 0.36], atol=1e-6)
        np.testing.assert_allclose([end.x - start.x, end.y - start.y, end.z - start.z],
                                   [0.06, 0.0, 0.0], atol=1e-6)

        Q = np.array([[0.0] * 6, [0.1, 0.2, -0.1, 0.0, 0.3, 0.0], [0.2, 0.4, -0.2, 0.1, 0.5, 0.0]])
        msg = demand_messages.make_demands(Q, goal_id='7')
        assert wait_until(lambda: h.demands.publish(msg) or h.latest('planned_path'), LIMIT,
                          h.spin)
        path = h.latest('planned_path')[0]
        assert path.type == Marker.LINE_STRIP
        points = np.array([[p.x, p.y, p.z] for p in path.points])
        np.testing.assert_allclose(points, fk_batch(mover6(), Q)[:, :3, 3], atol=1e-5)
    finally:
        h.close()


def test_keep_out_boxes_follow_the_planner():
    """The planner's boxes and margin are shown, and a change of them follows at once."""
    h = Harness(planner_boxes=BOX)
    try:
        def margin_shown():
            table = h.latest('table')
            return len(table) == 2 and abs(table[1].scale.z - 0.05) < 1e-9
        assert wait_until(lambda: margin_shown() and len(h.latest('keep_out')) == 1, LIMIT,
                          h.spin)
        two = BOX + [-0.4, -0.4, 0.0, -0.3, -0.3, 0.1]
        h.planner.set_parameters([Parameter('keep_out_boxes', value=two)])
        assert wait_until(lambda: len(h.latest('keep_out')) == 2, LIMIT, h.spin)
    finally:
        h.close()


def test_a_malformed_goal_is_refused_and_the_node_goes_on():
    """
    A /pose_goal with a NaN in its quaternion (issue 31: it ended the node) is refused.

    The guard counts it with its code and reason, nothing is published because of it, and the
    next valid goal is shown. The same for a path goal with a NaN position and a demand with
    too few values.
    """
    h = Harness(planner_node='')
    try:
        assert wait_until(lambda: h.latest('table'), LIMIT, h.spin)
        bad = PoseStamped()
        bad.header.frame_id = 'base_link'
        bad.pose.orientation.w, bad.pose.orientation.x = 1.0, float('nan')
        published = len(h.received)
        assert wait_until(lambda: h.goal.publish(bad) or h.markers.guard.total() >= 3, LIMIT,
                          h.spin)
        assert h.markers.guard.refused['/pose_goal'] >= 3
        assert h.markers.guard.last[:2] == ('/pose_goal', 'non_finite')
        assert 'quaternion' in h.markers.guard.last[2], h.markers.guard.last
        assert wait_until(lambda: h.demands.publish(Float32MultiArray(data=[0.1] * 5))
                          or '/joint_demands' in h.markers.guard.refused, LIMIT, h.spin)
        assert len(h.received) == published and h.latest('goal') == []
        good = PoseStamped()
        good.header.frame_id = 'base_link'
        good.pose = conversions.matrix_to_pose(np.eye(4))
        assert wait_until(lambda: h.goal.publish(good) or h.latest('goal'), LIMIT, h.spin)
        assert h.markers.guard.failed == 0
    finally:
        h.close()
