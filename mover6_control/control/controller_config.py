"""
The controller's settings (``ControllerConfig``) and what follows from them for one arm.

``derive_config`` checks a config against an arm and returns a frozen ``DerivedConfig``: the
per-joint goal and settle tolerances, the velocity limits in the driver's units, the control
period and, for a driver with a cycle, its ticks and the least speed that moves one tick per
cycle. ``ControllerCore`` installs it whole (``reconfigure``), so nothing of a config is read
half from one and half from another.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from mover6_control.control.commands import driver_velocity_limits, JOG_UNITS, min_jog_speed
from mover6_control.control.profiles import LawConfig
from mover6_control.control.servo import ServoConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, MOVER6_DRIVER_CYCLE, MOVER6_TICK_SIZE
from mover6_control.parameters import CONTROLLER   # the defaults
from mover6_control.validation import as_positive
import numpy as np

# Driver cycles until a command's move shows in the readings. The vendor's driver reads the
# encoders and moves at the same cycle: a command taken at one cycle shows two readings later.
# This package's CAN driver (``cycle_driver``) reads each module's reply at the cycle after the
# set-point it answers, and a module answers before it moves: one reading later still.
VENDOR_READING_LAG = 2
CYCLE_READING_LAG = 3


@dataclass(frozen=True)
class ControllerConfig:
    """
    The controller's settings (the node's parameters).

    ``goal_tolerance`` [rad] (scalar or (n,)): settled when every joint is this close.
    ``state_timeout`` [s]: joint states older than this are stale. ``position_gain`` [1/s]: the
    closed-loop gain on the position error. ``settle_timeout`` [s]: give up settling (result
    'aborted'). ``path_tolerance`` [rad]: a tracking error above it aborts the motion with a
    controlled stop. ``rate`` [Hz]: the tick rate, for the position-limit guard.
    ``jog_units``: 'rad_per_s' or 'fraction_of_max' (the vendor driver, which moves at
    ``value * max speed * speed_override``). 'fraction_of_max' only: ``driver_tick_size`` (n,)
    [rad] one encoder tick per joint and ``driver_cycle`` [s] the driver's cycle (defaults: the
    Mover6's), for the dead-zone compensation and the goal tolerance of at least one tick.
    ``cycle_driver``: the driver behind /JointJog integrates the command into set-points at
    ``driver_cycle`` and reports once per cycle (this package's CAN driver, in either unit), so
    the same in-flight compensation and whole-tick settling apply in 'rad_per_s';
    'fraction_of_max' implies it. ``settle_tolerance`` [rad]: after arriving (inside
    ``goal_tolerance``, result 'arrived') the controller keeps converging until every joint is
    this close (behind a driver with a cycle: one tick per joint, ``driver_tick_size``, what
    the driver resolves) or ``settle_time`` [s] has passed, then holds with a zero command.
    """

    law: LawConfig = field(default_factory=LawConfig)
    goal_tolerance: object = CONTROLLER['goal_tolerance'].default
    state_timeout: float = CONTROLLER['state_timeout'].default
    position_gain: float = CONTROLLER['position_gain'].default
    settle_timeout: float = CONTROLLER['settle_timeout'].default
    path_tolerance: float = CONTROLLER['path_tolerance'].default
    rate: float = CONTROLLER['rate'].default
    jog_units: str = CONTROLLER['jog_units'].default
    speed_override: float = CONTROLLER['speed_override'].default
    driver_tick_size: tuple = MOVER6_TICK_SIZE
    driver_cycle: float = MOVER6_DRIVER_CYCLE
    cycle_driver: bool = False
    settle_tolerance: float = 0.0001
    settle_time: float = 1.0
    servo: ServoConfig = field(default_factory=ServoConfig)   # jogging (control.servo)

    def __post_init__(self):
        """Check every setting."""
        for name in ('state_timeout', 'settle_timeout', 'path_tolerance', 'rate',
                     'settle_tolerance'):
            as_positive(getattr(self, name), name)
        if not (np.isfinite(self.settle_time) and self.settle_time >= 0.0):
            raise InvalidInputError(f'settle_time must be >= 0, got {self.settle_time}')
        if not (np.isfinite(self.position_gain) and self.position_gain >= 0.0):
            raise InvalidInputError(f'position_gain must be >= 0, got {self.position_gain}')
        tol = np.asarray(self.goal_tolerance, dtype=float)
        if not np.all(np.isfinite(tol)) or np.any(tol <= 0.0):
            raise InvalidInputError(f'goal_tolerance must be positive, got {tol.tolist()}')
        if self.jog_units not in JOG_UNITS:
            raise InvalidInputError(f'jog_units must be one of {JOG_UNITS}, got '
                                    f'"{self.jog_units}"')
        if not (0.0 < self.speed_override <= 1.0):
            raise InvalidInputError(f'speed_override must be in (0, 1], got '
                                    f'{self.speed_override}')
        ticks = np.asarray(self.driver_tick_size, dtype=float)
        if ticks.ndim != 1 or not ticks.size:
            raise InvalidInputError(f'driver_tick_size must be one value per joint, got '
                                    f'{self.driver_tick_size!r}')
        min_jog_speed(ticks, self.driver_cycle)          # raises on non-positive values
        object.__setattr__(self, 'driver_tick_size', tuple(float(t) for t in ticks))


def config_changes(old: ControllerConfig, new: ControllerConfig) -> list:
    """Return ``[(name, new value)]`` of the settings (law settings included) that differ."""
    changes = []
    for name in ControllerConfig.__dataclass_fields__:
        a, b = getattr(old, name), getattr(new, name)
        if name == 'law':
            changes += [(key, getattr(b, key)) for key in type(b).__dataclass_fields__
                        if getattr(a, key) != getattr(b, key)]
        elif name == 'servo':
            changes += [(f'servo_{key}', getattr(b, key)) for key in type(b).__dataclass_fields__
                        if getattr(a, key) != getattr(b, key)]
        elif not np.array_equal(np.asarray(a), np.asarray(b)):
            changes.append((name, b))
    return changes


@dataclass(frozen=True, eq=False)
class DerivedConfig:
    """
    A config checked against one arm, and what follows from it (``derive_config``).

    ``goal_tolerance`` and ``settle_tolerance`` (n,) [rad] per joint (at least one tick, and one
    tick, behind a driver with a cycle); ``velocity_limits`` (n,) [rad/s] what the driver can
    reach at ``speed_override``; ``dt`` [s] the control period; ``ticks`` (n,) [rad] and
    ``min_speed`` (n,) [rad/s] for a driver with a cycle, None otherwise; ``log_length`` how many
    ticks of commands the in-flight estimate keeps; ``reading_lag`` the driver cycles after which
    a command's move shows in the readings (``VENDOR_READING_LAG`` or ``CYCLE_READING_LAG``).
    """

    config: ControllerConfig
    goal_tolerance: np.ndarray
    settle_tolerance: np.ndarray
    velocity_limits: np.ndarray
    ticks: Optional[np.ndarray]
    min_speed: Optional[np.ndarray]
    dt: float
    log_length: int
    reading_lag: int

    @property
    def whole_tick_driver(self) -> bool:
        """Return whether a driver with a cycle is behind the commands (moves in flight)."""
        return self.ticks is not None


def derive_config(arm: ArmModel, config: ControllerConfig) -> DerivedConfig:
    """
    Return ``config`` and what follows from it, for ``arm``; raise when they do not fit.

    Reads nothing of a controller's state, changes nothing: ``ControllerCore`` installs it.
    """
    if not isinstance(config, ControllerConfig):
        raise InvalidInputError(f'config must be a ControllerConfig, got {config!r}')
    n = arm.n_joints
    tol = np.broadcast_to(np.asarray(config.goal_tolerance, float), (n,)).copy()
    settle_tol = np.minimum(np.full(n, config.settle_tolerance), tol)
    vlim = driver_velocity_limits(arm.velocity_limits, config.jog_units,
                                  config.speed_override)
    ticks = min_speed = None
    if config.jog_units == 'fraction_of_max' or config.cycle_driver:
        # A driver with a cycle (the vendor's, or ours in either unit): its readings lag
        # up to two cycles, so compensate what is in flight; goal tolerance >= one tick.
        ticks = np.asarray(config.driver_tick_size, dtype=float)
        if ticks.shape != (n,):
            raise InvalidInputError(f'driver_tick_size has {ticks.size} values for '
                                    f'{n} joints: give one per joint')
        min_speed = min_jog_speed(ticks, config.driver_cycle)
        slow = np.flatnonzero(min_speed > vlim)
        if slow.size:
            names = ', '.join(f'{arm.joint_names[i]} (needs {min_speed[i]:.3f} rad/s, '
                              f'can {vlim[i]:.3f})' for i in slow)
            raise InvalidInputError(
                f'at speed_override {config.speed_override} the driver cannot move one '
                f'tick per cycle of {config.driver_cycle} s: {names}; raise '
                f'speed_override')
        tol = np.maximum(tol, ticks)
        settle_tol = ticks.copy()      # what the driver resolves: one tick per joint
    lag = CYCLE_READING_LAG if config.cycle_driver else VENDOR_READING_LAG
    log_length = int(np.ceil((lag + 2) * config.driver_cycle * config.rate)) + 2
    return DerivedConfig(config, tol, settle_tol, vlim, ticks, min_speed, 1.0 / config.rate,
                         log_length, lag)
