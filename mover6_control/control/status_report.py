"""
What the controller says about itself: the ``Status`` to publish (``StatusReport.status``).

The state, a level ('OK', 'WARN', 'ERROR'), a human message and the named values, whose keys are
``status.StatusKey``: the motion and its progress, the tracking error, the settings in force (and
those pending until the motion ends), how the last motion ended, the last refusal, jogging.

``StatusReport`` is made with what it reads: the arm (its joint count), the robot (the tracking
error, the goal tolerances), the ``CoreState`` of ``controller_core.ControllerCore`` (the state
machine, the motion's figures, the settings) and jogging's ``JogSession``; it changes nothing.
A test builds it alone from those.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import config_changes
from mover6_control.control.core_state import CoreState
from mover6_control.control.jogging import JogSession
from mover6_control.control.robot import Robot
from mover6_control.control.status import StatusKey as K
from mover6_control.kinematics.arm import ArmModel
import numpy as np


@dataclass(frozen=True)
class Status:
    """What goes out on /controller/status: state, level, human message, named values."""

    state: str
    level: str
    message: str
    values: dict


class StatusReport:
    """The status of one arm's controller (module docstring)."""

    def __init__(self, arm: ArmModel, robot: Robot, core_state: CoreState,
                 jog_session: JogSession):
        """Report on ``arm`` (its model ``robot``) from ``core_state`` and ``jog_session``."""
        self.arm = arm
        self.robot = robot
        self.core_state = core_state
        self.jog_session = jog_session

    def status(self) -> Status:
        """Return the ``Status`` to publish now (state, level, reason, figures)."""
        shared = self.core_state
        config = shared.config
        moving = shared.state in sm.MOVING_STATES
        error = self.robot.error if moving else np.zeros(self.arm.n_joints)
        values = {
            K.STATE: shared.state,
            K.MOTION_ID: shared.motion_id,
            K.WAYPOINT: shared.waypoint,
            K.WAYPOINTS: shared.waypoints_total,
            K.TRACKING_ERROR: f'{float(np.linalg.norm(error)):.6f}',
            K.MAX_JOINT_ERROR: f'{float(np.max(np.abs(error))):.6f}',
            K.PROFILE: config.law.profile,
            K.JOG_UNITS: config.jog_units,
            K.RATE: f'{config.rate:g}',
            K.GOAL_TOLERANCE: ' '.join(f'{t:.6f}' for t in self.robot.goal_tolerances),
            K.SPEED_SCALING: f'{shared.speed_scaling.factor:.3f}',
            K.SPEED_SCALING_INPUT: f'{shared.speed_scaling.target:.3f}',
        }
        if shared.pending is not None:
            pending = shared.pending.config
            values[K.PENDING_PARAMETERS] = ', '.join(
                f'{name} {value}' for name, value in config_changes(config, pending))
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
