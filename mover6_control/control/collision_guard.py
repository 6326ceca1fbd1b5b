"""
The controller's collision check of a demand, as its velocity law will move the arm.

A demand the controller receives directly (/joint_demands, the FollowJointTrajectory action)
has not been through the planner's check, and the law does not move straight between its
waypoints (splines round the corners, a moving start bends the first segment). So the
``MotionPlan`` itself is sampled, in time, and the samples are checked like a planned path:
densely (``collision.checker.densify``, no joint step above ``max_joint_step`` between samples),
against the same shapes (``collision.checker.CollisionChecker``). ROS-free, clock-free.
"""

from __future__ import annotations

import re

from mover6_control.collision.checker import CollisionChecker, CollisionSettings, densify
from mover6_control.control.motion_plan import MotionPlan
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
import numpy as np

# [s] the law's reference is sampled this often, the samples joined by straight lines. A line
# misses a reference accelerating at a [rad/s^2] by at most a * dt^2 / 8: 0.2 mrad at the
# default a_max of 1 rad/s^2, far inside the table margin. Sampling every max_joint_step at the
# fastest joint's speed instead (5.7 ms) cost 30 ms per 3 s motion in MotionPlan.sample calls.
SAMPLE_PERIOD = 0.04


def plan_samples(plan: MotionPlan, max_joint_step: float,
                 period: float = SAMPLE_PERIOD) -> np.ndarray:
    """
    Return positions (m, n) [rad] of ``plan`` over its whole duration, at most one step apart.

    The reference is sampled every ``period`` [s], end included, and the samples are joined by
    straight lines sampled every ``max_joint_step`` [rad] (``densify``).
    """
    times = np.append(np.arange(0.0, plan.duration, period), plan.duration)
    Q = plan.positions(times)
    return densify(Q, max_joint_step)[0]


class CollisionGuard:
    """
    A callable that raises ``InvalidInputError`` for a ``MotionPlan`` that collides.

    The controller core calls it on every demand it plans (``ControllerCore.collision_guard``);
    the refusal names the shapes, the depth and where along the motion.
    """

    def __init__(self, arm: ArmModel, settings: CollisionSettings | None = None):
        """Build the checker of ``arm`` with ``settings``."""
        self.arm = arm
        self.settings = CollisionSettings() if settings is None else settings
        self.checker = CollisionChecker(arm, self.settings)

    def __call__(self, plan: MotionPlan) -> None:
        """Raise ``InvalidInputError`` ('collision: ...') when ``plan`` collides anywhere."""
        if not self.settings.enabled:
            return
        Q = plan_samples(plan, self.settings.max_joint_step)
        check = self.checker.check_configurations(Q, escape=True)   # Q[0]: where it is
        if not check.free:
            raise InvalidInputError(
                f'collision: {self.checker.message(check).replace("the path", "the motion")}; '
                'demand refused')

    def veto(self, q: np.ndarray, q_ahead: np.ndarray) -> str | None:
        """
        Return why a jog from ``q`` towards ``q_ahead`` (n,) [rad] must halt, or None.

        The servo's hook (``servo.ServoConfig.veto``): the straight joint motion between the two
        is checked densely; a contact the arm is already in may get shallower, not deeper.
        """
        if not self.settings.enabled:
            return None
        Q = densify(np.array([q, q_ahead], dtype=float), self.settings.max_joint_step)[0]
        check = self.checker.check_configurations(Q, escape=True)
        if check.free:
            return None
        return 'collision ahead: ' + re.sub(r' at \d+ % of the path$', '',
                                            self.checker.message(check))
