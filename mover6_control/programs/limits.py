"""
The limits a program is checked and timed against: Pilz's Cartesian limits and the joints'.

The Cartesian limits are MoveIt's (``config/moveit/pilz_cartesian_limits.yaml``, the Pilz
planner's LIN and CIRC bound): a ``lin`` or ``circ`` tool speed above them is refused at load.
The joint limits are the arm's speeds and the controller's ``a_max`` (the parameter table).
"""

from __future__ import annotations

from dataclasses import dataclass
import os

from mover6_control.kinematics.arm import ArmModel
from mover6_control.parameters import CONTROLLER
from mover6_control.programs.program_error import ProgramError
from mover6_control.resources import CONFIG_DIR
import numpy as np
import yaml

PILZ_LIMITS_FILE = os.path.join(CONFIG_DIR, 'moveit', 'pilz_cartesian_limits.yaml')


@dataclass(frozen=True)
class CartesianLimits:
    """Pilz's Cartesian limits: tool speed [m/s], acceleration [m/s^2], turn rate [rad/s]."""

    max_trans_vel: float
    max_trans_acc: float
    max_rot_vel: float

    @classmethod
    def load(cls, path: str = PILZ_LIMITS_FILE) -> CartesianLimits:
        """Return the limits of the file at ``path`` (key ``cartesian_limits``)."""
        try:
            with open(path, encoding='utf-8') as f:
                table = yaml.safe_load(f)['cartesian_limits']
            limits = cls(float(table['max_trans_vel']), float(table['max_trans_acc']),
                         float(table['max_rot_vel']))
        except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as err:
            raise ProgramError(path, 0, f'no Cartesian limits read: {err}', 'bad_value') from None
        if min(limits.max_trans_vel, limits.max_trans_acc, limits.max_rot_vel) <= 0.0:
            raise ProgramError(path, 0, f'Cartesian limits must be > 0, got {limits}',
                               'bad_value')
        return limits


@dataclass(frozen=True)
class JointLimits:
    """Each joint's speed [rad/s] and acceleration [rad/s^2] limit."""

    velocity: np.ndarray
    acceleration: np.ndarray

    @classmethod
    def of(cls, arm: ArmModel, a_max: float | None = None) -> JointLimits:
        """Return the arm's speed limits and ``a_max`` (default the controller's)."""
        a = CONTROLLER['a_max'].default if a_max is None else a_max
        return cls(np.array(arm.velocity_limits, dtype=float),
                   np.full(arm.n_joints, float(a)))

    def scaled(self, fraction: float) -> JointLimits:
        """Return the limits at a speed fraction: speeds times it, accelerations its square."""
        return JointLimits(self.velocity * fraction, self.acceleration * fraction ** 2)
