"""
A worker thread that hands queued jobs, in the order they came, to one function.

The controller's demand thread and the planner's planning thread are each one: a callback of the
executor queues a job (a demand, a goal) and returns at once, the thread takes the jobs one after
another, and the node closes it when it is destroyed. ``handle`` never raises (each user turns
every error into a refusal with its reason: no job ends without a status); ``wake`` wakes a job
that waits for something when the thread is closed (the joint states' event).
"""

import queue
import threading
from typing import Callable


class JobThread:
    """Take queued jobs in order and hand each to ``handle`` (module docstring)."""

    def __init__(self, name: str, handle: Callable[[object], None],
                 wake: Callable[[], None] = lambda: None):
        """Make the thread ``name`` (not started: ``start``); ``wake`` runs on ``close``."""
        self.handle = handle
        self.wake = wake
        self.running = True
        self.queue = queue.SimpleQueue()   # jobs not yet taken; None: the thread ends
        self.thread = threading.Thread(target=self.take_jobs, name=name, daemon=True)

    def start(self) -> None:
        """Start taking jobs."""
        self.thread.start()

    def put(self, job: object) -> None:
        """Queue ``job`` (not None) behind the others."""
        self.queue.put(job)

    def empty(self) -> bool:
        """Return True when every queued job has been taken."""
        return self.queue.empty()

    def stop(self) -> None:
        """Take no further job (the one being handled finishes); ``close`` ends the thread."""
        self.running = False

    def close(self, timeout: float) -> None:
        """Stop, wake a job that waits, and wait up to ``timeout`` [s] for the thread to end."""
        self.running = False
        self.queue.put(None)
        self.wake()
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout=timeout)

    def take_jobs(self) -> None:
        """Hand the queued jobs to ``handle`` in order until the thread is stopped or closed."""
        while True:
            job = self.queue.get()
            if job is None or not self.running:
                return
            self.handle(job)
