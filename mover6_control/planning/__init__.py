"""
Planning layer: from the current configuration and a pose goal to joint waypoints (n, 6).

Imports the base modules, ``kinematics`` and ``motion``; no ROS.
"""
