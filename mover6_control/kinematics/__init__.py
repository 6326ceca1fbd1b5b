"""
Kinematics layer: the arm model, FK and Jacobian, closed-form and numeric IK, path IK.

Imports only the base modules (``errors``, ``resources``, ``validation``); nothing above it.
"""
