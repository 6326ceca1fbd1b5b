"""
The controller's settings in force: install a config whole, now or at the end of a motion.

``CoreSettings`` checks a ``ControllerConfig`` against the arm
(``controller_config.derive_config``) and installs what follows from it everywhere at once: the
robot's goal tolerances and encoder ticks, the driver compensation's ticks, and the
``DerivedConfig`` in the ``CoreState`` every part of ``controller_core.ControllerCore`` reads.
A config that comes while a motion runs waits (``CoreState.pending``) for the tick after it
ends, so a motion runs with one config from start to end. A test builds it alone from the arm,
the robot, the compensation and a ``CoreState``.
"""

from __future__ import annotations

from typing import Optional

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import (ControllerConfig, derive_config,
                                                      DerivedConfig)
from mover6_control.control.core_state import CoreState
from mover6_control.control.driver_compensation import DriverCompensation
from mover6_control.control.robot import Robot
from mover6_control.kinematics.arm import ArmModel


class CoreSettings:
    """The settings in force and pending of one arm's controller (module docstring)."""

    def __init__(self, arm: ArmModel, robot: Robot, driver_compensation: DriverCompensation,
                 core_state: CoreState):
        """Install configs for ``arm`` in ``robot``, ``driver_compensation`` and ``core_state``."""
        self.arm = arm
        self.robot = robot
        self.driver_compensation = driver_compensation
        self.core_state = core_state

    def check(self, config: ControllerConfig) -> DerivedConfig:
        """Return what follows from ``config``; raise ``InvalidInputError`` when it cannot fit."""
        return derive_config(self.arm, config)

    def apply(self, derived: DerivedConfig) -> None:
        """Install ``derived``: the robot's limits, the driver's ticks, then it whole."""
        self.robot.set_limits(derived.goal_tolerance, derived.config.law.a_max, derived.ticks)
        self.driver_compensation.configure(derived)
        self.core_state.speed_scaling.set_acceleration_limit(derived.config.law.a_max)
        self.core_state.derived = derived

    def reconfigure(self, config: ControllerConfig) -> bool:
        """
        Use ``config`` from now on, or from the end of the running motion; return True if now.

        Idle (or waiting, or in fault) it applies at once: tolerances, velocity limits, the
        control period, the driver's ticks. While executing, settling or stopping it is kept
        pending (``pending_parameters`` in the status) and applied on the first tick after the
        motion ends (``apply_pending``); a later call replaces a pending config. Raises
        ``InvalidInputError`` (nothing changed) when it does not fit.
        """
        derived = self.check(config)
        shared = self.core_state
        shared.changed = True
        if shared.state in sm.MOVING_STATES:
            shared.pending = derived
            return False
        shared.pending = None
        self.apply(derived)
        return True

    def apply_pending(self) -> None:
        """Install the pending config once no motion runs (a tick's end); else nothing."""
        shared = self.core_state
        if shared.pending is not None and shared.state not in sm.MOVING_STATES:
            self.apply(shared.pending)      # the motion ended: the new config now
            shared.pending = None
            shared.changed = True

    @property
    def pending_config(self) -> Optional[ControllerConfig]:
        """Return the config waiting for the running motion to end (None when none)."""
        pending = self.core_state.pending
        return None if pending is None else pending.config
