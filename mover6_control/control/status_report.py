"""
What the controller says about itself: the ``Status`` to publish (``StatusReport.status``).

The state, a level ('OK', 'WARN', 'ERROR'), a human message and the named values, whose keys are
``status.StatusKey``: the motion and its progress, the tracking error, the settings in force (and
those pending until the motion ends), how the last motion ended, the last refusal, jogging.

``StatusReport`` is a part of ``controller_core.ControllerCore``: it reads the core's
``core_state`` (``control.core_state.CoreState``), ``robot``, ``config`` and ``jog_session``;
it is not used on its own.
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
        shared = self.core_state
        moving = shared.state in sm.MOVING_STATES
        error = self.robot.error if moving else np.zeros(self.arm.n_joints)
        values = {
            K.STATE: shared.state,
            K.MOTION_ID: shared.motion_id,
            K.WAYPOINT: shared.waypoint,
            K.WAYPOINTS: shared.waypoints_total,
            K.TRACKING_ERROR: f'{float(np.linalg.norm(error)):.6f}',
            K.MAX_JOINT_ERROR: f'{float(np.max(np.abs(error))):.6f}',
            K.PROFILE: self.config.law.profile,
            K.JOG_UNITS: self.config.jog_units,
            K.RATE: f'{self.config.rate:g}',
            K.GOAL_TOLERANCE: ' '.join(f'{t:.6f}' for t in self.robot.goal_tolerances),
        }
        if shared.pending is not None:
            pending = shared.pending.config
            values[K.PENDING_PARAMETERS] = ', '.join(
                f'{name} {value}' for name, value in config_changes(self.config, pending))
        if shared.timing:
            values[K.TIMING] = shared.timing
        if shared.motion_profile:
            values[K.MOTION_PROFILE] = shared.motion_profile
        values.update(shared.result)
        values.update(shared.rejection)
        jog = self.jog_session
        if shared.state == sm.JOGGING:
            values.update(jog.values)
        if jog.refused:
            values[K.JOG_REFUSED] = jog.refused
        return Status(shared.state, shared.level, shared.message, values)
