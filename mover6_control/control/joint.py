"""
One joint of the arm: what the Mover6 report's ``Joint`` class holds, as a small frozen value.

The Mover6 report keeps per joint a name, the measured value, the demand, the state at the start of
the move and a velocity, and computes the sign of the move and the trapezoidal velocity (eq.
16-18). This keeps the same facts plus the joint's limits, and fixes the report's sign at zero
distance (a division by zero there: here a joint at its demand has direction 0).
"""

from dataclasses import dataclass, replace
import math

from mover6_control.errors import InvalidInputError


@dataclass(frozen=True)
class Joint:
    """
    A revolute joint: limits, the latest measurement and the current demand.

    ``q`` [rad] and ``qd`` [rad/s] are the measured position and velocity; ``demand`` [rad] is the
    position the joint is sent to and ``q_initial`` [rad] the measured position when that demand
    was set (the Mover6 report's ``init_state``). ``lower``/``upper`` [rad] are the position limits
    and ``velocity_limit`` [rad/s] the speed limit.
    """

    name: str
    lower: float
    upper: float
    velocity_limit: float
    q: float = 0.0
    qd: float = 0.0
    demand: float = 0.0
    q_initial: float = 0.0

    def __post_init__(self):
        """Check that the limits make sense and every value is finite."""
        if not self.name:
            raise InvalidInputError('a joint needs a name')
        if math.isnan(self.lower) or math.isnan(self.upper) or self.lower > self.upper:
            raise InvalidInputError(
                f'joint {self.name}: limits [{self.lower}, {self.upper}] are not an interval')
        if not (math.isfinite(self.velocity_limit) and self.velocity_limit > 0.0):
            raise InvalidInputError(
                f'joint {self.name}: velocity limit must be positive, got {self.velocity_limit}')
        for field in ('q', 'qd', 'demand', 'q_initial'):
            if not math.isfinite(getattr(self, field)):
                raise InvalidInputError(f'joint {self.name}: {field} is not finite')

    def with_measurement(self, q, qd=0.0):
        """Return a copy with a new measured position [rad] and velocity [rad/s]."""
        return replace(self, q=float(q), qd=float(qd))

    def with_demand(self, demand):
        """
        Return a copy sent to ``demand`` [rad], remembering the present position as the start.

        Raises ``InvalidInputError`` when the demand is outside the joint's limits.
        """
        demand = float(demand)
        if not self.within_limits(demand):
            raise InvalidInputError(
                f'joint {self.name}: demand {demand:.4f} rad outside '
                f'[{self.lower:.4f}, {self.upper:.4f}]')
        return replace(self, demand=demand, q_initial=self.q)

    def within_limits(self, q, tol=1e-9):
        """Return True when ``q`` [rad] is inside the limits, with ``tol`` [rad]."""
        return self.lower - tol <= q <= self.upper + tol

    @property
    def distance_to_go(self):
        """Return ``demand - q`` [rad], signed."""
        return self.demand - self.q

    @property
    def direction(self):
        """Return the sign of the move still to go: -1, 0 or +1 (the Mover6 report's ``Sign``)."""
        d = self.distance_to_go
        return 0.0 if d == 0.0 else math.copysign(1.0, d)

    def trapezoidal_velocity(self, t, t_max, t_blend=None):
        """
        Return the trapezoidal velocity [rad/s] at ``t`` [s] after the start (Mover6 report 16-18).

        ``V_max = |demand - q_initial| / (t_max - t_blend)`` (eq. 16); the velocity ramps up
        over ``t_blend``, holds ``V_max`` and ramps down to zero at ``t_max`` (eq. 18), so its
        integral is ``demand - q_initial`` (eq. 19). The sign is that of ``demand - q_initial``
        (the planned move): unlike the report's ``Sign()`` of the remaining distance, it does not
        flip when the joint overshoots; correcting that is the closed loop's job.
        """
        t_blend = t_max / 4.0 if t_blend is None else t_blend
        check_trapezoid_times(t_max, t_blend)
        delta = self.demand - self.q_initial
        v_max = abs(delta) / (t_max - t_blend)
        sign = 0.0 if delta == 0.0 else math.copysign(1.0, delta)
        if t < 0.0 or t >= t_max:
            return 0.0
        if t < t_blend:
            return sign * v_max / t_blend * t
        if t < t_max - t_blend:
            return sign * v_max
        return sign * v_max * (1.0 - (t - (t_max - t_blend)) / t_blend)


def check_trapezoid_times(t_max, t_blend):
    """Raise unless ``0 < t_blend < t_max / 2`` (the Mover6 report: a symmetric trapezoid)."""
    if not (math.isfinite(t_max) and t_max > 0.0):
        raise InvalidInputError(f't_max must be positive, got {t_max}')
    if not (math.isfinite(t_blend) and 0.0 < t_blend < t_max / 2.0):
        raise InvalidInputError(
            f't_blend must satisfy 0 < t_blend < t_max / 2 = {t_max / 2.0}, got {t_blend}')
