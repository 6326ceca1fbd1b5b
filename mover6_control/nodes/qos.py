"""
The quality of service of the status topics (/planner/status, /controller/status): one home.

Transient local, so a reader that starts late gets the last status at once. A writer keeps only
the last one (depth 1: it is a state, not a log); a reader that must see every status, such as
the controller's 'rejected' report before the next status replaces it, reads with
``STATUS_READER_QOS`` (depth 10).

``LATCHED_QOS`` (transient local, depth 1) is robot_state_publisher's for /robot_description
and /tf_static, and the markers': a reader that starts late (RViz) gets the last message.
"""

from rclpy.qos import DurabilityPolicy, QoSProfile

STATUS_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
STATUS_READER_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
