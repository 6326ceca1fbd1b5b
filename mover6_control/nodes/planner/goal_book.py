"""
The planner's goal counter and its stop line: each goal's id, and which goals ~/stop dropped.

A goal's id is its header stamp and the planner's counter, ``<sec>.<nanosec>-<seq>``; ~/stop
drops every goal counted so far (``stopped``), wherever it is: queued, being planned, or sent
and not yet answered.
"""

import threading

from std_msgs.msg import Header


class GoalBook:
    """Count the goals; remember up to which ~/stop dropped them (module docstring)."""

    def __init__(self):
        """Start with no goal."""
        self.lock = threading.Lock()
        self.seq = 0
        self.stopped_seq = 0         # goals up to this seq were dropped by ~/stop

    def new_goal(self, header: Header) -> dict:
        """Return the next goal's ids: ``goal_id``, ``goal_stamp``, ``goal_seq``."""
        with self.lock:
            self.seq += 1
            seq = self.seq
        stamp = f'{header.stamp.sec}.{header.stamp.nanosec:09d}'
        return {'goal_id': f'{stamp}-{seq}', 'goal_stamp': stamp, 'goal_seq': seq}

    def stop(self) -> int:
        """Drop every goal counted so far; return the last one's seq."""
        with self.lock:
            self.stopped_seq = self.seq
            return self.stopped_seq

    def stopped(self, goal: dict) -> bool:
        """Return True when ~/stop dropped ``goal``."""
        return goal['goal_seq'] <= self.stopped_seq
