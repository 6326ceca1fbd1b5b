"""
Control layer: the controller without ROS, joint states and demands in, velocity commands out.

``Joint`` and ``Robot`` (the arm the controller drives), the profiles and their planners (a
demand to a ``MotionPlan``, ``TimedPlan`` for a trajectory's own timing), the state machine, the
controller core and its parts (states check, demand intake, collision guard, motion ticks,
commands, jogging with ``servo``, the status), the driver compensation.

Imports the base modules, ``kinematics``, ``collision`` and ``motion``; no ROS.
"""
