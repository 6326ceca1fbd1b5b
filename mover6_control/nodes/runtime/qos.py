"""
The quality of service of the status topics and of the 100 Hz streams' readers: one home.

Transient local, so a reader that starts late gets the last status at once. A writer keeps only
the last one (depth 1: it is a state, not a log); a reader that must see every status, such as
the controller's 'rejected' report before the next status replaces it, reads with
``STATUS_READER_QOS`` (depth 10).

``LATCHED_QOS`` (transient local, depth 1) is robot_state_publisher's for /robot_description
and /tf_static, and the markers': a reader that starts late (RViz) gets the last message.

``STREAM_READER_QOS`` (best effort) is how the nodes read the 100 Hz streams /joint_states and
/JointJog, as ROS reads sensor data: a sample lost is replaced by the next one 10 ms later, and
a reliable reader would cost every sample an acknowledgement and its writer the bookkeeping
(each node's Fast DDS event thread busy with them). The writers stay reliable, so reliable
readers (a recorder, robot_state_publisher, the driver) are served too; a best-effort reader
matches either.
``LATEST_READER_QOS`` is the same for a reader that only keeps the latest sample (the planner).
"""

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

STATUS_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
STATUS_READER_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)

STREAM_READER_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
LATEST_READER_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
