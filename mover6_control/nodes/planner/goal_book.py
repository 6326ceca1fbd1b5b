"""
The planner's goal counter and its stop line: each goal's id, and which goals ~/stop dropped.

A goal (``Goal``, frozen) is its ids and the velocity law it asked for: its id is its header
stamp and the planner's counter, ``<sec>.<nanosec>-<seq>``. ~/stop drops every goal counted so far
(``stopped``), wherever it is: queued, being planned, or sent and not yet answered.
"""

from dataclasses import dataclass
import threading

from std_msgs.msg import Header


@dataclass(frozen=True)
class Goal:
    """
    One goal: ``goal_id``, ``stamp`` and ``seq`` (module docstring), and its ``profile``.

    ``profile``: the controller's velocity law named by the goal's header ('' for the
    controller's own), forwarded with the demand.
    """

    goal_id: str
    stamp: str
    seq: int
    profile: str = ''

    def values(self) -> dict:
        """Return the status values that say which goal a status is about."""
        out = {'goal_id': self.goal_id, 'goal_stamp': self.stamp, 'goal_seq': self.seq}
        if self.profile:
            out['profile'] = self.profile
        return out


class GoalBook:
    """Count the goals; remember up to which ~/stop dropped them (module docstring)."""

    def __init__(self):
        """Start with no goal."""
        self.lock = threading.Lock()
        self.seq = 0
        self.stopped_seq = 0         # goals up to this seq were dropped by ~/stop

    def new_goal(self, header: Header) -> Goal:
        """Return the next goal, counted, with the ids of ``header``'s stamp."""
        with self.lock:
            self.seq += 1
            seq = self.seq
        stamp = f'{header.stamp.sec}.{header.stamp.nanosec:09d}'
        return Goal(f'{stamp}-{seq}', stamp, seq)

    def stop(self) -> int:
        """Drop every goal counted so far; return the last one's seq."""
        with self.lock:
            self.stopped_seq = self.seq
            return self.stopped_seq

    def stopped(self, goal: Goal) -> bool:
        """Return True when ~/stop dropped ``goal``."""
        return goal.seq <= self.stopped_seq
