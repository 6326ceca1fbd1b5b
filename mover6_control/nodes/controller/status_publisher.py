"""
The controller's status on /controller/status: the core's, with the goal and the tick figures.

Published on every change and at ``status_rate`` (``due``), transient local. ``status_lock``
orders the publications: taken before the core's ``lock``, never while holding it, so statuses
go out in the order they were read and the core's lock is never held while publishing.
"""

import threading
from typing import Optional

from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.status import StatusKey
from mover6_control.nodes.controller.goal_ledger import GoalLedger
from mover6_control.nodes.controller.tick_figures import TickFigures
from mover6_control.nodes.messages import conversions
from rclpy.publisher import Publisher


class StatusPublisher:
    """Publish the controller's status (module docstring)."""

    def __init__(self, publisher: Publisher, core: ControllerCore, lock: threading.RLock,
                 goals: GoalLedger, figures: TickFigures, period: float):
        """Publish ``core``'s status (read under ``lock``) every ``period`` [s] at least."""
        self.publisher = publisher
        self.core = core
        self.lock = lock
        self.goals = goals
        self.figures = figures
        self.period = period
        self.status_lock = threading.Lock()
        self.last = None             # node clock [s] of the latest status (under lock)

    def due(self, now: float) -> bool:
        """Return whether a status is due at ``now`` [s] by the period (call under ``lock``)."""
        return self.last is None or now - self.last >= self.period or now < self.last

    def publish(self, now: float, extra: Optional[dict] = None, level: Optional[str] = None,
                message: Optional[str] = None) -> None:
        """Publish the core's status (plus ``extra`` values); never call it holding ``lock``."""
        with self.status_lock:
            with self.lock:
                status = self.core.status()
                self.last = now
                goal_id = self.goals.goal_of(int(status.values.get(StatusKey.MOTION_ID, 0)))
            values = dict(status.values)
            values[StatusKey.GOAL_ID] = goal_id
            values.update(self.figures.values())     # max_tick_gap, max_states_age
            values.update(extra or {})
            self.publisher.publish(conversions.make_status(
                'controller', level or status.level, message or status.message, values))
