"""
Doubles of a ``PlanJob`` for test_plan_worker.py: jobs that die, sleep or fail in the worker.

In a module of their own with nothing heavy to import: the worker imports it to unpickle them.
"""

import os
import signal
import time

import numpy as np


class DyingJob:
    """A job whose planning kills its process (a crash of the worker)."""

    waypoints = np.zeros((1, 6))

    def run(self, guard=None):
        """Die with SIGKILL."""
        os.kill(os.getpid(), signal.SIGKILL)


class SlowJob:
    """A job whose planning takes ``seconds`` (longer than the worker allows)."""

    waypoints = np.zeros((1, 6))

    def __init__(self, seconds, started=None):
        """Plan for ``seconds``; first create the file ``started`` (a path; None: none)."""
        self.seconds = seconds
        self.started = started

    def run(self, guard=None):
        """Say it started (the file), then sleep."""
        if self.started is not None:
            with open(self.started, 'w'):
                pass
        time.sleep(self.seconds)


class Unpicklable(Exception):
    """An exception that cannot be pickled back (its class takes two arguments)."""

    def __init__(self, a, b):
        """Keep both."""
        super().__init__(f'{a} {b}')


class FailingJob:
    """A job that raises an exception that does not pickle."""

    waypoints = np.zeros((1, 6))

    def run(self, guard=None):
        """Raise it."""
        raise Unpicklable('no', 'pickle')
