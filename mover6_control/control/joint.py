"""
One joint of the arm: what the Mover6 report's ``Joint`` class holds, as a small frozen value.

The Mover6 report keeps per joint a name, the measured value, the demand, the state at the start of
the move and a velocity, and computes the sign of the move and the trapezoidal velocity (eq.
16-18). This keeps the same facts plus what the controller needs of a joint: its limits
(position, velocity, acceleration), its goal tolerance and, for the vendor driver, its encoder
tick; and fixes the report's sign at zero distance (a division by zero there: here a joint at
its demand has direction 0). The report's trapezoidal velocity is the controller's trapezoidal
profile (``motion_plan.trapezoid_segment``, the law of ``motion.time_laws``), not a copy here;
so are its measurement, demand and arrival: ``Robot.measure``, ``Robot.give``, and the
controller's settling (``motion_ticks``). ``control.robot.Robot`` holds the joints of the arm
the controller drives and hands out ``Joint`` values of its present state.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Optional

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_positive


@dataclass(frozen=True)
class Joint:
    """
    A revolute joint: limits, the latest measurement and the current demand.

    ``q`` [rad] and ``qd`` [rad/s] are the measured position and velocity; ``demand`` [rad] is the
    position the joint is sent to and ``q_initial`` [rad] the measured position when that demand
    was set (the Mover6 report's ``init_state``). ``lower``/``upper`` [rad] are the position
    limits, ``velocity_limit`` [rad/s] the speed limit and ``acceleration_limit`` [rad/s^2] the
    acceleration limit (inf: none). ``goal_tolerance`` [rad]: the joint has arrived this close
    to its demand. ``encoder_tick`` [rad]: one tick of a driver that moves whole ticks (the
    Mover6's vendor driver), None for a driver that takes velocities.
    """

    name: str
    lower: float
    upper: float
    velocity_limit: float
    q: float = 0.0
    qd: float = 0.0
    demand: float = 0.0
    q_initial: float = 0.0
    acceleration_limit: float = math.inf
    goal_tolerance: float = 0.002
    encoder_tick: Optional[float] = None

    def __post_init__(self):
        """Check that the limits make sense and every value is finite."""
        if not self.name:
            raise InvalidInputError('a joint needs a name')
        if math.isnan(self.lower) or math.isnan(self.upper) or self.lower > self.upper:
            raise InvalidInputError(
                f'joint {self.name}: limits [{self.lower}, {self.upper}] are not an interval')
        as_positive(self.velocity_limit, f'joint {self.name}: velocity limit')
        if not self.acceleration_limit > 0.0:
            raise InvalidInputError(f'joint {self.name}: acceleration limit must be > 0, got '
                                    f'{self.acceleration_limit}')
        as_positive(self.goal_tolerance, f'joint {self.name}: goal tolerance')
        if self.encoder_tick is not None:
            as_positive(self.encoder_tick, f'joint {self.name}: encoder tick')
        for field in ('q', 'qd', 'demand', 'q_initial'):
            if not math.isfinite(getattr(self, field)):
                raise InvalidInputError(f'joint {self.name}: {field} is not finite')

    @property
    def distance_to_go(self) -> float:
        """Return ``demand - q`` [rad], signed."""
        return self.demand - self.q

    @property
    def direction(self) -> float:
        """Return the sign of the move still to go: -1, 0 or +1 (the Mover6 report's ``Sign``)."""
        d = self.distance_to_go
        return 0.0 if d == 0.0 else math.copysign(1.0, d)
