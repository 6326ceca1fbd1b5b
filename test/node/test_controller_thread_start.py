"""
The controller's threads start only once the node is whole (found by bench churn, issue 12).

With ``tick_priority`` the real-time tick thread ran before ``__init__`` had finished, published
a status, and died on a missing attribute: the controller never ticked. Here a started thread
runs at once, in the caller, the worst order a scheduler can choose.
"""

import threading

from mover6_control.nodes.controller import tick_loop
from mover6_control.nodes.controller.action_thread import ActionThread
from mover6_control.nodes.controller.node import ControllerNode
from mover6_control.nodes.controller.tick_loop import TickLoop
from mover6_control.nodes.runtime.job_thread import JobThread
import pytest
import rclpy

NS = 'thread_start'


class RunsAtOnce(threading.Thread):
    """A thread whose ``start`` runs its target in the caller, before ``start`` returns."""

    def start(self):
        """Run the target now (an exception propagates to the caller)."""
        self.run()


def test_threads_start_after_every_attribute_exists(monkeypatch):
    ran = []

    def one_tick(ticks):
        ticks.status.publish(0.0)      # what a real-time tick thread does first
        ran.append('tick')

    monkeypatch.setattr(tick_loop.threading, 'Thread', RunsAtOnce)
    monkeypatch.setattr(TickLoop, 'run_ticks', one_tick)
    monkeypatch.setattr(JobThread, 'take_jobs', lambda jobs: ran.append(jobs.thread.name))
    monkeypatch.setattr(ActionThread, 'serve', lambda actions: ran.append('actions'))
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ControllerNode(context=context, namespace=NS)
        # The tick raises the others with it: they run before it.
        assert ran == ['controller_demands', 'actions', 'tick']
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


if __name__ == '__main__':
    pytest.main([__file__])
