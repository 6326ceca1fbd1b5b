"""
The planner's status on /planner/status: its readiness, and what became of each goal.

Every status says whether the planner is ready (value ``state``: ``waiting_for_states`` or
``ready``), then the goal it is about (``goal_id``, ``goal_stamp``, ``goal_seq``), then its
values (``result``, ``reason`` ...). ``status_lock`` orders the publications.
"""

import threading
from typing import Optional

from mover6_control.control.status import PlannerResult, PlannerState
from mover6_control.kinematics.rotations import matrix_to_euler_zyx
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.planner.goal_book import Goal
import numpy as np
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher

# The details of an UnreachableError that a refusal carries as status values.
DETAIL_KEYS = ('waypoint', 'position_error', 'orientation_error', 'fraction', 'shapes', 'depth')


class PlannerStatus:
    """Publish the planner's status (module docstring)."""

    def __init__(self, publisher: Publisher, logger: RcutilsLogger):
        """Publish on ``publisher``; the planner starts waiting for /joint_states."""
        self.publisher = publisher
        self.logger = logger
        self.lock = threading.Lock()           # state
        self.status_lock = threading.Lock()    # one publication at a time
        self.state = PlannerState.WAITING_FOR_STATES

    def set_state(self, state: PlannerState) -> None:
        """Say on the status that the planner is ready, or waiting for /joint_states."""
        with self.lock:
            if self.state == state:
                return
            self.state = state
        if state == PlannerState.READY:
            self.logger.info('planner ready: /joint_states received')
            self.publish('OK', 'ready: waiting for goals', {})
        else:
            self.publish('WARN', 'waiting for /joint_states', {})

    def refuse(self, motion: str, text: str, reason: str, details: dict, goal: Goal,
               result: PlannerResult = PlannerResult.REFUSED) -> None:
        """Report a goal refused (or ``result`` failed) with ``reason``: status and log."""
        values = {'result': result, 'motion': motion, 'reason': reason}
        for key in DETAIL_KEYS:
            if key in details:
                values[key] = details[key]
        closest = details.get('closest_pose')
        if closest is not None:
            T = np.asarray(closest)
            values['closest_pose_xyzabc'] = ' '.join(
                f'{v:.4f}' for v in list(T[:3, 3]) + list(matrix_to_euler_zyx(T[:3, :3])))
        word = 'refused' if result == PlannerResult.REFUSED else 'failed'
        self.logger.error(f'goal {goal.goal_id} {word} ({reason}): {text}')
        self.publish('ERROR', f'goal {word} ({reason}): {text}', values, goal)

    def publish(self, level: str, text: str, values: dict, goal: Optional[Goal] = None) -> None:
        """Publish /planner/status: ``state``, then the goal it is about (if any), then values."""
        merged = {'state': self.state}
        merged.update(goal.values() if goal is not None else {})
        merged.update(values)
        with self.status_lock:
            self.publisher.publish(conversions.make_status('planner', level, text, merged))
