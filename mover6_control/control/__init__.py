"""
Control layer: ``Joint``, ``Robot``, the velocity laws, the state machine, the controller core.

Imports the base modules, ``kinematics`` and ``motion``; no ROS.
"""
