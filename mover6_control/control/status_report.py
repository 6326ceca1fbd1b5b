"""
What the controller says about itself: the ``Status`` to publish (``StatusReport.status``).

The state, a level ('OK', 'WARN', 'ERROR'), a human message and the named values, whose keys are
``status.StatusKey``: the motion and its progress, the tracking error, the settings in force (and
those pending until the motion ends), how the last motion ended, the last refusal, jogging.

``StatusReport`` is a part of ``controller_core.ControllerCore`` (its state is the core's, set in
``ControllerCore.__init__``); it is not used on its own.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import config_changes
from mover6_control.control.status import StatusKey as K
import numpy as np


@dataclass(frozen=True)
class Status:
    """What goes out on /controller/status: state, level, human message, named values."""

    state: str
    level: str
    message: str
    values: dict


class StatusReport:
    """The status of ``ControllerCore`` (module docstring)."""

    def status(self) -> Status:
        """Return the ``Status`` to publish now (state, level, reason, figures)."""
        moving = self._state in sm.MOVING_STATES
        error = self.robot.error if moving else np.zeros(self.arm.n_joints)
        values = {
            K.STATE: self._state,
            K.MOTION_ID: self._motion_id,
            K.WAYPOINT: self._waypoint,
            K.WAYPOINTS: self._waypoints_total,
            K.TRACKING_ERROR: f'{float(np.linalg.norm(error)):.6f}',
            K.MAX_JOINT_ERROR: f'{float(np.max(np.abs(error))):.6f}',
            K.PROFILE: self.config.law.profile,
            K.JOG_UNITS: self.config.jog_units,
            K.RATE: f'{self.config.rate:g}',
            K.GOAL_TOLERANCE: ' '.join(f'{t:.6f}' for t in self.robot.goal_tolerances),
        }
        if self._pending_config is not None:
            pending = self._pending_config.config
            values[K.PENDING_PARAMETERS] = ', '.join(
                f'{name} {value}' for name, value in config_changes(self.config, pending))
        if self._timing:
            values[K.TIMING] = self._timing
        if self._motion_profile:
            values[K.MOTION_PROFILE] = self._motion_profile
        values.update(self._result)
        values.update(self._rejection)
        jog = self.jog_session
        if self._state == sm.JOGGING:
            values.update(jog.values)
        if jog.refused:
            values[K.JOG_REFUSED] = jog.refused
        return Status(self._state, self._level, self._message, values)
