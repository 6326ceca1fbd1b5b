"""
Speed scaling: the factor at which a motion's plan time runs, as joint_trajectory_controller's.

A plan ``q(tau)`` is followed at plan time ``tau``; speed scaling makes ``tau`` run at the
factor ``s`` (``tau' = s``), so the reference is ``(q(tau), s qd(tau))``: the path is the
plan's, only its timing changes (a Cartesian line stays on its line), 0 holds the arm where
the path is, and a later factor above 0 goes on from there.

The factor asked for (``request``, from ``~/speed_scaling_input`` or any other part of the
controller) is not taken at once: the factor in force (``factor``) ramps towards it so that
the feedforward velocity ``s qd(tau)`` never changes by more than ``a_max dt`` a tick of
``dt``. ``advance`` finds, each tick, the largest step of the factor towards the target that
keeps every joint within that bound, sampling the plan itself at the candidate plan times (a
secant search of a few samples while the factor ramps, one sample once it is there); a path
that is itself at the limit keeps the factor until it is not.

``check_factor`` is the validation where a factor enters: finite and within ``[0, MAX_FACTOR]``.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence, Tuple

from mover6_control.errors import InvalidInputError
import numpy as np

# The largest factor taken: 1.0 is the plan's own timing (the plan is within the limits there;
# faster would break them).
MAX_FACTOR = 1.0
# Secant refinements of a ramping tick's step before it keeps the factor as it is.
REFINEMENTS = 4

Sample = Callable[[float], Tuple[np.ndarray, np.ndarray]]


def check_factor(value: object) -> float:
    """Return ``value`` as a factor, or raise ``InvalidInputError`` naming it."""
    if isinstance(value, bool):
        raise InvalidInputError(f'speed scaling factor {value!r} is not a number')
    try:
        factor = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f'speed scaling factor {value!r} is not a number')
    if not math.isfinite(factor) or factor < 0.0 or factor > MAX_FACTOR:
        raise InvalidInputError(f'speed scaling factor {factor!r} is not within '
                                f'[0, {MAX_FACTOR:g}]: ignored')
    return factor


class SpeedScaling:
    """
    The factor motions run at (``factor``) and the one asked for (``target``).

    ``request(value)`` asks for a factor (0 a pause along the path, 1 the plan's own timing);
    the factor in force follows it within the acceleration limit, tick by tick, through
    ``advance``. See the module docstring.
    """

    def __init__(self, n_joints: int, a_max: float | Sequence[float], initial: float = 1.0):
        """Scale ``n_joints`` joints' plans within ``a_max`` [rad/s^2], from ``initial``."""
        self.target = check_factor(initial)
        self.factor = self.target
        self.a_max = np.broadcast_to(np.asarray(a_max, dtype=float), (n_joints,)).copy()

    def request(self, value: object) -> float:
        """Ask for the factor ``value`` (checked by ``check_factor``); return it."""
        self.target = check_factor(value)
        return self.target

    @property
    def paused(self) -> bool:
        """Return whether motions stand still (the factor in force is 0)."""
        return self.factor == 0.0

    def set_acceleration_limit(self, a_max: float | Sequence[float]) -> None:
        """Bound the factor's rate by ``a_max`` [rad/s^2] (a scalar or (n,))."""
        self.a_max = np.broadcast_to(np.asarray(a_max, dtype=float), self.a_max.shape).copy()

    def advance(self, tau: float, dt: float,
                sample: Sample) -> Tuple[float, np.ndarray, np.ndarray]:
        """
        Advance plan time ``tau`` [s] by a tick of ``dt`` [s] on the path ``sample``.

        ``sample(tau)`` gives the plan's ``(q, qd)`` at full speed. Returns the new plan time,
        its position (n,) [rad] and the feedforward velocity (n,) [rad/s] at the factor in
        force, which moves towards the target as far as the acceleration limit allows.
        """
        s = self.factor
        want = self.target - s
        if want == 0.0 or dt <= 0.0:
            return self._at(tau, dt, s, sample)
        v_old = s * sample(tau)[1]
        lim = self.a_max * dt
        base = self._at(tau, dt, s, sample)
        bound = np.maximum(lim, np.abs(base[2] - v_old))   # a path at its limit keeps s
        trial, lam = self._at(tau, dt, s + want, sample), 1.0
        for _ in range(REFINEMENTS):
            if np.all(np.abs(trial[2] - v_old) <= bound):
                self.factor = min(max(s + lam * want, 0.0), MAX_FACTOR)
                return trial
            # Secant between the factor kept (lam 0) and the trial: the largest lam within.
            a, c = base[2] - v_old, (trial[2] - base[2]) / lam
            with np.errstate(divide='ignore', invalid='ignore'):
                below = np.where(c < 0.0, (-bound - a) / c, np.inf)
                room = np.where(c > 0.0, (bound - a) / c, below)
            lam = min(lam, float(np.min(room))) * (1.0 - 1e-9)
            if lam <= 0.0:
                break
            trial = self._at(tau, dt, s + lam * want, sample)
        return base

    @staticmethod
    def _at(tau: float, dt: float, s: float,
            sample: Sample) -> Tuple[float, np.ndarray, np.ndarray]:
        """Return (plan time, position, feedforward velocity) one tick on at factor ``s``."""
        t = tau + s * dt
        q, qd = sample(t)
        return t, q, s * qd
