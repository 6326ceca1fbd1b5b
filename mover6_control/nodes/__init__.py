"""
ROS 2 nodes: the planner and the controller, and the one message-conversion module.

With ``mover6_control.tools`` (the goal command line, the teleop, the demo) and the bridge node
(``sim_bridge.bridge_node`` and its physics thread), the only places that import rclpy or
message packages (``test/architecture/test_core_is_ros_free.py`` checks it). Nodes declare
parameters, convert messages to core values, call the core, publish.
"""
