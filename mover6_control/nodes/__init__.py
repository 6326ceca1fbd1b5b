"""
ROS 2 nodes: the planner and the controller, and the one message-conversion module.

The only place in this package (with ``sim_bridge.bridge_node``) that imports rclpy or message
packages. Nodes declare parameters, convert messages to core values, call the core, publish.
"""
