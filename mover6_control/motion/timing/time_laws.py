"""
Time laws: normalised progress ``s(tau)`` from 0 to 1 over normalised time ``tau`` in [0, 1].

A time law turns a straight joint move into a trajectory (the Jacobians and trajectories report eq.
29-32)::

    q(t)    = q_i + (q_f - q_i) s(tau),   tau = t / T
    qd(t)   = (q_f - q_i) s'(tau) / T
    qdd(t)  = (q_f - q_i) s''(tau) / T**2
    qddd(t) = (q_f - q_i) s'''(tau) / T**3

Laws here: the cubic ``-2 tau^3 + 3 tau^2``, the quintic 3-4-5, the septic 4-5-6-7, the Mover6
report trapezoid with a blend time (eq. 16-18), the sharp trapezoid of the Jacobians and
trajectories report (three equal thirds) and the Jacobians and trajectories report's via-point
polynomial of degree 6 through ``s(tau_via) = S``.

This module is the one home of the Mover6 report's trapezoid: ``trapezoid_times`` checks
``0 < t_blend < t_max / 2`` (default ``t_max / 4``) and ``TrapezoidalTimeLaw`` is the profile.
The controller's trapezoidal law (``control.motion_plan.trapezoid_segment``), ``Joint`` and
``Robot`` (``control.joint``, ``control.robot``) and the joint trajectories all play it.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_positive
import numpy as np


def _as_tau(tau):
    if isinstance(tau, float):          # one time of a control tick: no array machinery
        if not math.isfinite(tau):
            raise InvalidInputError(f'tau is not finite: {tau}')
        return min(max(tau, 0.0), 1.0)
    tau = np.asarray(tau, dtype=float)
    if not np.isfinite(tau).all():
        raise InvalidInputError(f'tau has non-finite values: {tau.tolist()}')
    # np.minimum / np.maximum rather than np.clip: several times faster on the scalars of a
    # control tick (the controller's trapezoidal law samples this law every tick).
    return np.minimum(np.maximum(tau, 0.0), 1.0)


@dataclass(frozen=True)
class PolynomialTimeLaw:
    """
    A polynomial time law ``s(tau) = sum_k coefficients[k] tau^k`` (ascending powers).

    Outside [0, 1] ``tau`` is clamped: the law holds its start and end.
    """

    name: str
    coefficients: Sequence[float]

    def __post_init__(self):
        """Validate and freeze the coefficients."""
        c = np.asarray(self.coefficients, dtype=float)
        if c.ndim != 1 or c.size < 2 or not np.all(np.isfinite(c)):
            raise InvalidInputError(f'coefficients must be finite, 1-D, length >= 2: {c}')
        object.__setattr__(self, 'coefficients', tuple(float(x) for x in c))
        # s and its first three derivatives, made once: the controller samples them every tick.
        poly = np.polynomial.Polynomial(self.coefficients)
        object.__setattr__(self, '_polys', (poly,) + tuple(poly.deriv(k) for k in (1, 2, 3)))

    def evaluate(self, tau: float | np.ndarray, derivative: int = 0) -> np.ndarray:
        """Return ``d^k s / d tau^k`` at ``tau`` (scalar or array) for ``derivative`` k."""
        tau = _as_tau(tau)
        if 0 <= derivative < len(self._polys):
            return self._polys[derivative](tau)
        return self._polys[0].deriv(derivative)(tau)

    def __call__(self, tau: float | np.ndarray) -> np.ndarray:
        """Return ``s(tau)``."""
        return self.evaluate(tau)


def _piece(up, down, ramp_up, cruise, ramp_down):
    """Return the trapezoid's piece at each tau: ramp up, cruise or ramp down."""
    if isinstance(up, bool):            # one tau (a control tick): no arrays
        return ramp_up if up else ramp_down if down else cruise
    return np.where(up, ramp_up, np.where(down, ramp_down, cruise))


@dataclass(frozen=True)
class TrapezoidalTimeLaw:
    """
    Trapezoidal velocity law: ramp up for ``blend`` of the time, cruise, ramp down.

    ``blend`` = t_blend / t_max in (0, 0.5). The Mover6 report eq. 16: the cruise speed
    ``s' = 1 / (1 - blend)`` makes the area under the trapezoid exactly 1 (eq. 19).
    """

    name: str
    blend: float

    def __post_init__(self):
        """Check that the blend fraction leaves a symmetric trapezoid."""
        b = float(self.blend)
        if not np.isfinite(b) or not 0.0 < b < 0.5:
            raise InvalidInputError(
                f't_blend must satisfy 0 < t_blend < t_max / 2 (blend fraction {b})')
        object.__setattr__(self, 'blend', b)

    @property
    def peak_rate(self) -> float:
        """Return the cruise value of ``s'`` (the Mover6 report eq. 16 with t_max = 1)."""
        return 1.0 / (1.0 - self.blend)

    def evaluate(self, tau: float | np.ndarray, derivative: int = 0) -> np.ndarray:
        """Return ``d^k s / d tau^k`` at ``tau`` for k in 0..3 (jerk is 0 between corners)."""
        tau = _as_tau(tau)
        b, v = self.blend, self.peak_rate
        a = v / b
        up = tau < b
        down = tau > 1.0 - b
        td = 1.0 - tau
        if derivative == 0:
            return _piece(up, down, 0.5 * a * tau ** 2, v * (tau - 0.5 * b),
                          1.0 - 0.5 * a * td ** 2)
        if derivative == 1:
            return _piece(up, down, a * tau, v, a * td)
        if derivative == 2:
            return _piece(up, down, a, 0.0, -a) * (tau < 1.0)
        if derivative == 3:
            return np.zeros_like(tau)
        raise InvalidInputError(f'derivative must be 0..3, got {derivative}')

    def __call__(self, tau: float | np.ndarray) -> np.ndarray:
        """Return ``s(tau)``."""
        return self.evaluate(tau)


def cubic() -> PolynomialTimeLaw:
    """Return the cubic law ``3 tau^2 - 2 tau^3`` (the 'trapezoidal polynomial' of the report)."""
    return PolynomialTimeLaw('cubic', (0.0, 0.0, 3.0, -2.0))


def quintic() -> PolynomialTimeLaw:
    """Return the 3-4-5 law ``10 tau^3 - 15 tau^4 + 6 tau^5`` (zero end acceleration)."""
    return PolynomialTimeLaw('quintic_345', (0.0, 0.0, 0.0, 10.0, -15.0, 6.0))


def septic() -> PolynomialTimeLaw:
    """Return the 4-5-6-7 law ``35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7`` (zero end jerk)."""
    return PolynomialTimeLaw('septic_4567', (0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0))


def trapezoid_times(t_max: float, t_blend: Optional[float] = None) -> tuple[float, float]:
    """
    Return ``(t_max, t_blend)`` [s] of the Mover6 report's trapezoid, checked.

    ``t_blend`` defaults to ``t_max / 4`` (the Mover6 report's choice); ``0 < t_blend < t_max / 2``
    is enforced (the Mover6 report section 2.2.4: a symmetric trapezoid with a cruise phase).
    """
    t_max = as_positive(t_max, 't_max')
    t_blend = t_max / 4.0 if t_blend is None else float(t_blend)
    if not np.isfinite(t_blend) or not 0.0 < t_blend < t_max / 2.0:
        raise InvalidInputError(
            f't_blend must satisfy 0 < t_blend < t_max / 2 = {t_max / 2.0}, got {t_blend}')
    return t_max, t_blend


def trapezoidal(t_max: float = 1.0, t_blend: Optional[float] = None) -> TrapezoidalTimeLaw:
    """
    Return the Mover6 report's trapezoid for a move of ``t_max`` [s], blend time ``t_blend`` [s].

    ``t_blend`` defaults to ``t_max / 4``; ``0 < t_blend < t_max / 2`` (``trapezoid_times``).
    """
    t_max, t_blend = trapezoid_times(t_max, t_blend)
    return TrapezoidalTimeLaw('trapezoidal', t_blend / t_max)


def sharp_trapezoid() -> TrapezoidalTimeLaw:
    """Return the sharp trapezoid: accelerate, cruise, decelerate in equal thirds."""
    return TrapezoidalTimeLaw('sharp_trapezoid', 1.0 / 3.0)


def via_fraction(theta_start: float, theta_via: float, theta_goal: float) -> float:
    """
    Return ``S`` with ``theta_via = theta_start + (theta_goal - theta_start) S``.

    As the Jacobians and trajectories report defines it.

    The Jacobians and trajectories report's example: ``via_fraction(83.14, 90, 173.37)`` =
    0.0760279.
    """
    vals = np.asarray([theta_start, theta_via, theta_goal], dtype=float)
    if not np.all(np.isfinite(vals)):
        raise InvalidInputError(f'angles must be finite: {vals.tolist()}')
    span = vals[2] - vals[0]
    if abs(span) < 1e-12:
        raise InvalidInputError('start and goal coincide: the via fraction is undefined')
    return float((vals[1] - vals[0]) / span)


def via_point_polynomial(s_via: float, tau_via: float = 0.5) -> PolynomialTimeLaw:
    """
    Return the Jacobians and trajectories report's degree-6 law through ``s(tau_via) = s_via``.

    Seven conditions: s(0) = s'(0) = s''(0) = 0, s(1) = 1, s'(1) = s''(1) = 0 and the via
    point. With ``s_via = 0.0760279`` at ``tau_via = 0.5`` the solution is the Jacobians and
    trajectories report's ``27.13 tau^6 - 75.40 tau^5 + 66.40 tau^4 - 17.13 tau^3``.
    """
    s_via = float(s_via)
    tau_via = float(tau_via)
    if not np.isfinite(s_via):
        raise InvalidInputError(f's_via must be finite, got {s_via}')
    if not np.isfinite(tau_via) or not 0.0 < tau_via < 1.0:
        raise InvalidInputError(f'tau_via must lie strictly inside (0, 1), got {tau_via}')
    powers = np.arange(7)
    rows = [
        (powers == 0).astype(float),                       # s(0)
        (powers == 1).astype(float),                       # s'(0)
        2.0 * (powers == 2),                               # s''(0)
        np.ones(7),                                        # s(1)
        powers.astype(float),                              # s'(1)
        powers * (powers - 1.0),                           # s''(1)
        tau_via ** powers,                                 # s(tau_via)
    ]
    rhs = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, s_via])
    coefficients = np.linalg.solve(np.array(rows, dtype=float), rhs)
    return PolynomialTimeLaw('via_point', coefficients)


def by_name(name: str, **kwargs: float) -> PolynomialTimeLaw | TrapezoidalTimeLaw:
    """Return a time law by name: cubic, quintic, septic, trapezoidal, sharp_trapezoid."""
    table = {'cubic': cubic, 'quintic': quintic, 'septic': septic,
             'trapezoidal': trapezoidal, 'sharp_trapezoid': sharp_trapezoid}
    if name not in table:
        raise InvalidInputError(f'unknown time law {name!r}; choose from {sorted(table)}')
    return table[name](**kwargs)
