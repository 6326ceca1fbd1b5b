"""
The driver's std_srvs/Trigger services, on a node and an executor of their own.

The services wait for the modules (seconds; referencing minutes): they are served by a node
(``<driver>_services``, no parameters) and a two-thread executor of their own, so the driver
node's single-threaded executor never waits and /JointJog arrives within a millisecond (a
multi-threaded executor for everything took 27 ms on average, its threads churning the
interpreter lock the control thread needs). Each service is ``~/<kind>`` of the driver node.
"""

import threading
from typing import Callable, Sequence

from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger


class TriggerServices:
    """
    Serve ``~/<kind>`` for each of ``kinds`` with ``run(kind) -> (success, message)``.

    ``node`` is the driver node (its name, namespace and context), ``guard`` its
    ``CallbackGuard`` (a service that raises answers false with the reason).
    """

    def __init__(self, node: Node, guard, kinds: Sequence[str],
                 run: Callable[[str], tuple[bool, str]]) -> None:
        self.run = run
        self.node = Node(f'{node.get_name()}_services', namespace=node.get_namespace(),
                         context=node.context, start_parameter_services=False,
                         use_global_arguments=False)
        base = node.get_fully_qualified_name()
        for kind in kinds:
            guard.service(Trigger, f'{base}/{kind}', self._callback(kind), on=self.node)
        self.executor = MultiThreadedExecutor(num_threads=2, context=node.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._serve, name='driver_services',
                                        daemon=True)
        self._thread.start()

    def _serve(self):
        try:
            self.executor.spin()
        except Exception:  # noqa: B902 - the context shut down: the node is closing
            pass

    def _callback(self, kind):
        def callback(request, response):
            response.success, response.message = self.run(kind)
            return response
        return callback

    def close(self) -> None:
        """Stop serving and destroy the services' node."""
        self.executor.shutdown(timeout_sec=5.0)
        self._thread.join(timeout=5.0)
        self.node.destroy_node()
