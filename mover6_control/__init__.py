"""Pose-goal motion for the Mover6: ROS-free core plus thin ROS 2 nodes."""
