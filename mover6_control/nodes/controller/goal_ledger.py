"""
The controller node's goal ledger: which motion each goal's demand became, or why it was refused.

A demand may name the goal it is for (the planner's goal id, or an action goal's): the status
echoes the goal of the running motion (``goal_id``), a demand sent again for a goal already taken
is not started twice, and the action server waits for its goal to be taken or refused and reads
when the motion's plan counts from. The ledger keeps the latest ``LEDGER_SIZE`` goals and motions
only (the planner stops sending a demand again after seconds), so it does not grow with every
motion. Every method takes the node's lock (reentrant: callers may already hold it), so the
ledger changes with the core under one lock.

The action server waits on a ``Future`` (``expect``) that the demand thread completes when it
takes or refuses the goal, instead of polling.
"""

from collections import OrderedDict
import threading
from typing import Optional, Union

from rclpy.executors import Executor
from rclpy.task import Future

# Goals (and motions) the ledger remembers; older ones are forgotten.
LEDGER_SIZE = 64


def _bounded_set(table: OrderedDict, key, value, size: int) -> None:
    """Set ``table[key] = value`` as the newest entry; drop the oldest beyond ``size``."""
    table[key] = value
    table.move_to_end(key)
    while len(table) > size:
        table.popitem(last=False)


class GoalLedger:
    """The goals of the controller's demands, bounded, under the node's lock (module doc)."""

    def __init__(self, lock: threading.RLock, size: int = LEDGER_SIZE):
        """Keep the latest ``size`` goals and motions; every method takes ``lock``."""
        self.lock = lock
        self.size = size
        self._motion_goals = OrderedDict()   # motion_id -> (goal id or '', start [s])
        self._outcomes = OrderedDict()       # goal id -> motion_id (int) or refusal (str)
        self._withdrawn = OrderedDict()      # goal ids their sender stopped waiting for
        self._waiting = {}                   # goal id -> Future of an action server

    def expect(self, goal_id: str, executor: Optional[Executor] = None) -> Future:
        """
        Return a ``Future`` done once ``goal_id`` is taken or refused (or the ledger closes).

        Its result is the motion id (int), the refusal (str), or None when the ledger closed.
        """
        future = Future(executor=executor)
        future.add_done_callback(lambda _: None)    # its completion wakes the executor
        with self.lock:
            outcome = self._outcomes.get(goal_id)
            if outcome is not None:
                future.set_result(outcome)
            else:
                self._waiting[goal_id] = future
        return future

    def known(self, goal_id: str) -> bool:
        """Return whether ``goal_id`` was taken or refused already."""
        with self.lock:
            return goal_id in self._outcomes

    def started(self, motion_id: int, goal_id: str, start: float) -> None:
        """Note that the demand of ``goal_id`` ('' none) became ``motion_id``, from ``start``."""
        with self.lock:
            _bounded_set(self._motion_goals, motion_id, (goal_id, start), self.size)
            if goal_id:
                self._settle(goal_id, motion_id)

    def refused(self, goal_id: str, reason: str) -> None:
        """Note that the demand of ``goal_id`` was refused, saying ``reason``."""
        with self.lock:
            self._settle(goal_id, reason)

    def _settle(self, goal_id, outcome):
        _bounded_set(self._outcomes, goal_id, outcome, self.size)
        future = self._waiting.pop(goal_id, None)
        if future is not None:
            future.set_result(outcome)

    def withdraw(self, goal_id: str) -> Union[int, str, None]:
        """
        Return the outcome of ``goal_id`` (motion id, or refusal); with none, withdraw it.

        A withdrawn goal is never started: decided under the lock that commits demands, so a
        goal is either taken or never. Returns None when it was withdrawn now.
        """
        with self.lock:
            outcome = self._outcomes.get(goal_id)
            if outcome is None:
                _bounded_set(self._withdrawn, goal_id, True, self.size)
                self._waiting.pop(goal_id, None)
            return outcome

    def withdrawn(self, goal_id: str) -> bool:
        """Return whether the sender of ``goal_id`` stopped waiting for it."""
        with self.lock:
            return goal_id in self._withdrawn

    def goal_of(self, motion_id: int) -> str:
        """Return the goal id of ``motion_id`` ('' for none, or forgotten)."""
        with self.lock:
            return self._motion_goals.get(motion_id, ('', None))[0]

    def start_of(self, motion_id: int) -> Optional[float]:
        """Return the node clock [s] the plan of ``motion_id`` counts from (None: unknown)."""
        with self.lock:
            return self._motion_goals.get(motion_id, ('', None))[1]

    def close(self) -> None:
        """Complete every waiting future with None (the node closes)."""
        with self.lock:
            waiting, self._waiting = self._waiting, {}
        for future in waiting.values():
            future.set_result(None)
