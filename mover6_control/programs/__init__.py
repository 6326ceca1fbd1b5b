"""Taught points and programs of moves: their files, their checks and their plans (ROS-free)."""
