"""
ROS 2 nodes, a folder each, and the parts they share.

The nodes: ``planner``, ``controller``, ``driver`` (the real arm's lifecycle node),
``state_publisher``, ``markers``, ``recorder`` and ``console``; the bridge's node
(``sim_bridge.bridge_node``) lives beside the simulator it runs. ``messages`` is the one
message-conversion package (core values in, messages out, and back); ``runtime`` the start,
shutdown, parameters, QoS, callback guard and DDS configuration every node uses.

With ``mover6_control.tools`` and the bridge node, the only places that import rclpy or message
packages (``test/architecture/test_core_is_ros_free.py`` checks it). Nodes declare parameters,
convert messages to core values, call the core, publish.
"""
