"""MuJoCo simulation of the Mover6: ROS-free simulator plus a thin ROS 2 node."""

import mover6_control  # noqa: F401 - first: numpy's OpenBLAS on one thread (its docstring)
