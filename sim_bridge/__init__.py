"""MuJoCo simulation of the Mover6: ROS-free simulator plus a thin ROS 2 node."""
