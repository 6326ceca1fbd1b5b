"""
A point's or a step's pose as X Y Z [m] A B C [rad], the Mover6 report's goal convention.

``R = R_home Rz(A) Ry(B) Rx(C)``, ``R_home`` the flange orientation at q = 0 (as the goal CLI
reads six numbers): ``0 0 0`` keeps the home orientation.
"""

from __future__ import annotations

from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import euler_zyx_near, goal_relative_to_start
import numpy as np

# Within this [rad] of gimbal lock (B = +-pi/2) a pose is written with B = +-pi/2.
LOCK_TOL = 1e-3


def pose_matrix(arm: ArmModel, x: float, y: float, z: float, a: float, b: float,
                c: float) -> np.ndarray:
    """Return the flange pose (4, 4) of X Y Z [m] A B C [rad]."""
    return goal_relative_to_start(fk(arm, np.zeros(arm.n_joints)), x, y, z, a, b, c)


def pose_numbers(arm: ArmModel, T: np.ndarray) -> tuple:
    """Return X Y Z [m] A B C [rad] of the flange pose ``T`` (4, 4) (``pose_matrix``)."""
    T = np.asarray(T, dtype=float)
    R = fk(arm, np.zeros(arm.n_joints))[:3, :3].T @ T[:3, :3]
    angles = euler_zyx_near(R, (0.0, 0.0, 0.0), lock_tol=LOCK_TOL)
    return tuple(float(v) for v in T[:3, 3]) + tuple(float(v) for v in angles)
