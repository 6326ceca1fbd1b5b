"""
The command of one tick: closed loop on the reference, velocity and position limits, jog units.

The command of every tick is ``closed_loop_command``: ``qd_ref + kp (q_ref - q)`` (the closed-loop
correction on the measured position), scaled by one common factor into the velocity limits,
then ``guard_position_limits`` so no joint is driven further past a limit; ``to_jog_units``
writes it in the driver's units.

For a driver that reads JointJog as fractions of the maximum speed and moves whole encoder ticks
per cycle (the Mover6's vendor driver), ``dead_zone_command`` lifts commands too small to move a
tick up to ``min_jog_speed`` while the error exceeds half a tick, and ``tick_pulse_command``
moves a joint whole ticks after arrival (see ``driver_compensation``).
"""

from __future__ import annotations

from typing import Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.parameters import JOG_UNITS   # the units to_jog_units takes
from mover6_control.validation import as_positive
import numpy as np


# --- limits ---------------------------------------------------------------------------------

def common_scale(qd: np.ndarray, velocity_limits: np.ndarray) -> float:
    """Return the factor >= 1 by which ``qd`` (n,) must be divided to respect the limits."""
    ratio = np.max(np.abs(qd) / velocity_limits)
    return max(1.0, float(ratio))


def scale_to_limits(qd: np.ndarray, velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return ``qd`` (n,) [rad/s] divided by one common factor so every ``|qd_i| <= limit_i``.

    The direction of motion in joint space is kept (unlike clipping each joint).
    """
    return qd / common_scale(qd, velocity_limits)


def guard_position_limits(qd: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                          dt: float) -> np.ndarray:
    """
    Return ``qd`` (n,) with no joint driven further past a limit, nor across it within ``dt``.

    A joint at or beyond a limit may only move back inside; a joint inside may move at most to
    the limit in one tick of ``dt`` [s]. This acts per joint: safety before direction.
    """
    qd = np.array(qd, dtype=float)
    room_up = np.maximum(upper - q, 0.0) / dt
    room_down = np.minimum(lower - q, 0.0) / dt
    return np.clip(qd, room_down, room_up)


def closed_loop_command(q_ref: np.ndarray, qd_ref: np.ndarray, q: np.ndarray, gain: float,
                        velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return the velocity command (n,) [rad/s]: feedforward plus correction, within the limits.

    ``qd = qd_ref + gain (q_ref - q)`` with ``gain`` [1/s] on the measured ``q`` [rad], then one
    common factor so no joint exceeds ``velocity_limits`` (n,) [rad/s].
    """
    return scale_to_limits(qd_ref + gain * (q_ref - q), velocity_limits)


def to_jog_units(qd: np.ndarray, velocity_limits: np.ndarray, units: str = 'rad_per_s',
                 speed_override: float = 0.25) -> np.ndarray:
    """
    Return the JointJog velocities for ``qd`` (n,) [rad/s] in the driver's ``units``.

    ``rad_per_s``: unchanged (ROS standard). ``fraction_of_max``: the vendor driver's reading,
    where it moves at ``value * velocity_limit * speed_override``; clipped to [-1, 1].
    """
    if units == 'rad_per_s':
        return np.asarray(qd, dtype=float)
    if units == 'fraction_of_max':
        return np.clip(np.asarray(qd) / (np.asarray(velocity_limits) * speed_override), -1.0, 1.0)
    raise InvalidInputError(f'jog_units must be one of {JOG_UNITS}, got "{units}"')


def driver_velocity_limits(velocity_limits: Sequence[float], units: str = 'rad_per_s',
                           speed_override: float = 0.25) -> np.ndarray:
    """Return the speeds (n,) [rad/s] the driver can reach in ``units`` (override applied)."""
    velocity_limits = np.asarray(velocity_limits, dtype=float)
    if units == 'fraction_of_max':
        return velocity_limits * speed_override
    return velocity_limits


# --- drivers that move whole encoder ticks per cycle (fraction_of_max) ----------------------

# The Mover6's tick sizes and driver cycle are arm facts: kinematics.arm.MOVER6_TICK_SIZE and
# MOVER6_DRIVER_CYCLE.
# The smallest command is this much above one tick per cycle, so that rounding in the driver
# cannot lose the tick (and below two ticks per cycle, so it cannot add one).
TICK_MARGIN = 1.05


def min_jog_speed(tick_size: Sequence[float], driver_cycle: float) -> np.ndarray:
    """
    Return the smallest speed (n,) [rad/s] that moves each joint one whole tick per cycle.

    ``tick_size`` (n,) [rad] is one encoder tick, ``driver_cycle`` [s] the driver's cycle; the
    result is ``TICK_MARGIN * tick_size / driver_cycle`` (Mover6 J5/J6: 0.129 rad/s, 7.4 deg/s).
    A driver that moves whole ticks per cycle does not move a joint commanded less.
    """
    tick_size = as_positive(tick_size, 'tick_size', np.size(tick_size))
    return TICK_MARGIN * tick_size / as_positive(driver_cycle, 'driver_cycle')


def dead_zone_command(qd: np.ndarray, error: np.ndarray, tick_size: np.ndarray,
                      min_speed: np.ndarray,
                      may_move: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return ``(qd, in_dead_zone)``: the command (n,) [rad/s] for a driver that moves whole ticks.

    Joints commanded at least ``min_speed`` (n,) [rad/s] keep ``qd``: the driver resolves them.
    Below it (``in_dead_zone``) the driver would not move the joint at all, so a joint whose
    position ``error`` (n,) [rad] exceeds half a tick (``tick_size`` (n,) [rad]) gets exactly
    ``min_speed`` towards the error when ``may_move`` (n,) bool allows it, and zero otherwise;
    a joint within half a tick (the nearest tick: nothing better exists) gets zero.
    """
    qd = np.asarray(qd, dtype=float)
    error = np.asarray(error, dtype=float)
    dead = np.abs(qd) < min_speed
    move = dead & np.asarray(may_move, dtype=bool) & (np.abs(error) > 0.5 * np.asarray(tick_size))
    out = np.where(dead, np.where(move, np.sign(error) * min_speed, 0.0), qd)
    return out, dead


def tick_pulse_command(error: np.ndarray, tick_size: np.ndarray, driver_cycle: float,
                       velocity_limits: np.ndarray) -> np.ndarray:
    """
    Return the speeds (n,) [rad/s] that move each joint whole ticks towards ``error`` in a cycle.

    For a driver that moves ``trunc(speed * driver_cycle / tick)`` ticks per cycle: each joint
    gets ``k = round(error / tick_size)`` ticks (``error`` (n,) [rad], ``tick_size`` (n,)
    [rad]), at most what ``velocity_limits`` (n,) [rad/s] allow in one ``driver_cycle`` [s],
    commanded as ``(|k| + TICK_MARGIN - 1) tick / cycle`` so the truncation gives exactly ``k``.
    Held for one driver cycle it closes the error to the nearest tick in one step (zero for a
    joint within half a tick).
    """
    tick_size = np.asarray(tick_size, dtype=float)
    k_max = np.maximum(np.floor(np.asarray(velocity_limits) * driver_cycle / tick_size
                                - (TICK_MARGIN - 1.0)), 1.0)
    k = np.minimum(np.abs(np.round(np.asarray(error, dtype=float) / tick_size)), k_max)
    return np.where(k > 0.0, np.sign(error) * (k + TICK_MARGIN - 1.0) * tick_size / driver_cycle,
                    0.0)
