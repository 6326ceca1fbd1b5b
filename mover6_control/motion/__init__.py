"""
Motion layer: Cartesian pose paths, time laws, joint trajectories, continuous timing, metrics.

Imports the base modules and ``kinematics``; nothing above it.
"""
