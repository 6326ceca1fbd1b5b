"""
The controller's action server on a node, an executor and a thread of its own.

rclpy builds a received goal as Python objects in the thread of the executor that serves the
action server: a 10,000-point ``FollowJointTrajectory`` goal is 10,000 ``JointTrajectoryPoint``
objects, hundreds of milliseconds on a loaded machine. Served by the controller node's executor,
that build held up ``on_joint_states`` for all of it, and the core faulted with '/joint_states
stale' (``state_timeout``). Here the server (``trajectory_server``) belongs to a second node,
``<controller>_actions`` in the controller's namespace, spun by a ``SingleThreadedExecutor`` in
the thread ``controller_actions``: the build shares only the interpreter lock with the states
intake, which changes hands every switch interval (``node.main``).

The action keeps its name, ``<controller's full name>/follow_joint_trajectory``
(``/controller/follow_joint_trajectory`` by default), resolved from the controller node, so
``ros2 action list`` and every client see it where they did; ``ros2 action info`` names the
server node ``controller_actions``. That node takes no global arguments (a ``__node:=``
remapping would give it the controller's name) and has no parameters: the goal's defaults come
from the controller's (``path_tolerance``, ``goal_tolerance``) and its waits run on the
controller's clock (sim time too).

The thread spins in slices of ``shutdown.SPIN_SLICE``, as the main thread; ``close`` ends it
(woken at once), then destroys the server and its node. Goals still running then end as they
did when the controller's executor stopped: the controller closed.
"""

import threading

from mover6_control.nodes.controller.trajectory_server import (ControllerParts,
                                                               FollowJointTrajectoryServer)
from mover6_control.nodes.runtime.shutdown import SPIN_SLICE
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

# [s] longest wait for the action thread to end at ``close``.
JOIN_TIMEOUT = 2.0


class ActionThread:
    """The controller's ``FollowJointTrajectoryServer`` served in a thread (module docstring)."""

    def __init__(self, controller: Node, parts: ControllerParts):
        """
        Make the node, the executor and the server of ``controller``; ``start`` serves it.

        ``controller`` names the action node (namespace, context, the action's name);
        ``parts`` are what the server uses of it.
        """
        self.node = Node(f'{controller.get_name()}_actions',
                         namespace=controller.get_namespace(), context=controller.context,
                         start_parameter_services=False, use_global_arguments=False)
        self.executor = SingleThreadedExecutor(context=controller.context)
        self.server = FollowJointTrajectoryServer(
            parts, self.node, self.executor,
            f'{controller.get_fully_qualified_name()}/follow_joint_trajectory')
        self.executor.add_node(self.node)
        self.running = True
        self.thread = threading.Thread(target=self.serve, name='controller_actions',
                                       daemon=True)

    def start(self) -> None:
        """Start serving (once the controller node is whole)."""
        self.thread.start()

    def serve(self) -> None:
        """Spin the action node until ``close`` or the context's shutdown (the thread)."""
        try:
            while self.running and self.node.context.ok():
                self.executor.spin_once(timeout_sec=SPIN_SLICE)
        except ExternalShutdownException:
            pass

    def close(self) -> None:
        """End the thread, then destroy the server, the executor and the node (once)."""
        if not self.running:
            return
        self.running = False
        if self.node.context.ok():
            self.executor.wake()
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout=JOIN_TIMEOUT)
        self.server.destroy()
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()
