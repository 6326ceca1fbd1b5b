"""
The robot as the Mover6 report's ``Robot`` class holds it: its joints, the synchronised law.

The Mover6 report eq. 1-2: the joint with the furthest to go sets the time ``t_max = max |demand -
q| / lambda_max``; every joint then moves at ``(demand - q) / t_max`` so all arrive together. The
controller itself works on arrays (``velocity_laws``); this class is the readable, per-joint view
of the same facts, built from an ``ArmModel`` and used for demands and checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, TYPE_CHECKING

from mover6_control.control.joint import Joint
from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_positive
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel


@dataclass(frozen=True)
class Robot:
    """A named arm: a tuple of ``Joint`` values in chain order."""

    name: str
    joints: Sequence[Joint]

    def __post_init__(self):
        """Freeze the joints into a tuple and check their names are unique."""
        joints = tuple(self.joints)
        if not joints:
            raise InvalidInputError('a robot needs at least one joint')
        if not all(isinstance(j, Joint) for j in joints):
            raise InvalidInputError('Robot.joints must hold Joint values')
        names = [j.name for j in joints]
        if len(set(names)) != len(names):
            raise InvalidInputError(f'joint names repeat: {names}')
        object.__setattr__(self, 'joints', joints)

    @classmethod
    def from_arm(cls, arm: ArmModel) -> Robot:
        """Return a robot at rest at q = 0 with the names and limits of an ``ArmModel``."""
        joints = tuple(
            Joint(name, float(lo), float(hi), float(v))
            for name, lo, hi, v in zip(arm.joint_names, arm.lower, arm.upper,
                                       arm.velocity_limits))
        return cls(arm.name, joints)

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return len(self.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Return the joint names in chain order."""
        return tuple(j.name for j in self.joints)

    def _array(self, field):
        return np.array([getattr(j, field) for j in self.joints], dtype=float)

    @property
    def q(self) -> np.ndarray:
        """Return the measured positions (n,) [rad]."""
        return self._array('q')

    @property
    def qd(self) -> np.ndarray:
        """Return the measured velocities (n,) [rad/s]."""
        return self._array('qd')

    @property
    def demand(self) -> np.ndarray:
        """Return the demanded positions (n,) [rad]."""
        return self._array('demand')

    @property
    def q_initial(self) -> np.ndarray:
        """Return the positions (n,) [rad] measured when the demand was set."""
        return self._array('q_initial')

    @property
    def lower(self) -> np.ndarray:
        """Return the lower position limits (n,) [rad]."""
        return self._array('lower')

    @property
    def upper(self) -> np.ndarray:
        """Return the upper position limits (n,) [rad]."""
        return self._array('upper')

    @property
    def velocity_limits(self) -> np.ndarray:
        """Return the velocity limits (n,) [rad/s]."""
        return self._array('velocity_limit')

    def _check(self, values, name):
        values = np.asarray(values, dtype=float)
        if values.shape != (self.n_joints,):
            raise InvalidInputError(
                f'{name} must have shape ({self.n_joints},), got {values.shape}')
        if not np.all(np.isfinite(values)):
            raise InvalidInputError(f'{name} has non-finite values: {values.tolist()}')
        return values

    def with_measurement(self, q: Sequence[float],
                         qd: Optional[Sequence[float]] = None) -> Robot:
        """Return a copy with measured positions (n,) [rad] and velocities (n,) [rad/s]."""
        q = self._check(q, 'q')
        qd = np.zeros(self.n_joints) if qd is None else self._check(qd, 'qd')
        joints = tuple(j.with_measurement(a, b) for j, a, b in zip(self.joints, q, qd))
        return Robot(self.name, joints)

    def with_demand(self, demand: Sequence[float]) -> Robot:
        """
        Return a copy sent to ``demand`` (n,) [rad], with the present positions as the start.

        Raises ``InvalidInputError`` naming every joint whose demand is outside its limits.
        """
        demand = self._check(demand, 'demand')
        bad = [f'{j.name}={d:.4f} outside [{j.lower:.4f}, {j.upper:.4f}]'
               for j, d in zip(self.joints, demand) if not j.within_limits(d)]
        if bad:
            raise InvalidInputError('demand outside joint limits: ' + ', '.join(bad))
        return Robot(self.name, tuple(j.with_demand(d) for j, d in zip(self.joints, demand)))

    def max_time(self, lambda_max: float) -> float:
        """
        Return ``t_max`` [s] (Mover6 report eq. 1) for the furthest joint at ``lambda_max``.

        ``t_max = max_m |demand_m - q_m| / lambda_max``; 0 when every joint is at its demand.
        """
        lambda_max = as_positive(lambda_max, 'lambda_max')
        return float(np.max(np.abs(self.demand - self.q)) / lambda_max)

    def synchronised_velocities(self, lambda_max: float) -> np.ndarray:
        """
        Return the joint speeds (n,) [rad/s] of the Mover6 report eq. 2: ``(demand - q) / t_max``.

        The furthest joint moves at ``lambda_max``; all joints arrive together. Zero when every
        joint is already at its demand.
        """
        t_max = self.max_time(lambda_max)
        if t_max == 0.0:
            return np.zeros(self.n_joints)
        return (self.demand - self.q) / t_max

    def trapezoidal_velocities(self, t: float, t_max: float,
                               t_blend: Optional[float] = None) -> np.ndarray:
        """Return every joint's trapezoidal velocity (n,) [rad/s] at ``t`` [s] (eq. 16-18)."""
        return np.array([j.trapezoidal_velocity(t, t_max, t_blend) for j in self.joints])
