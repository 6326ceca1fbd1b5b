"""
A lifecycle node's ``change_state`` service that answers a transition it does not have: false.

rclpy's ``LifecycleNode`` raises from its ``change_state`` service when asked for a transition
by id that the present state does not have (activate before configure): the exception would end
the executor's spin, and with it the node. ``UnknownTransitions`` wraps the service's callback
(before the node's ``CallbackGuard`` wraps every service) so such a request is answered false,
and the reason is kept and logged: the state machine's refusal, as ``ros2 lifecycle set`` reports
one by listing the transitions the state has.

rclpy has no public way to do this: the service is the node's private
``_service_change_state``, which this wraps. The crash is ros2/rclpy#1209, fixed upstream by
ros2/rclpy#1319; the rclpy of this Jazzy install still raises (test/node/test_driver_node.py
asks for activate while unconfigured). With a fixed rclpy the wrapper only adds the reason.
"""

from typing import Callable

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

TRANSITION_NAMES = {getattr(Transition, name): name[len('TRANSITION_'):].lower()
                    for name in dir(Transition) if name.startswith('TRANSITION_')}
"""A transition's id -> its name (configure, activate, ..., active_shutdown)."""


class UnknownTransitions:
    """
    Answer a transition the state machine does not have from its state false, with why.

    ``node`` is the lifecycle node; ``state()`` its state's label; ``failure(reason)`` notes and
    logs why a transition was refused.
    """

    def __init__(self, node, state: Callable[[], str], failure: Callable[[str], None]) -> None:
        self.state = state
        self.failure = failure
        service = node._service_change_state
        self.change = service.callback
        service.callback = self.on_change_state

    def on_change_state(self, request: ChangeState.Request,
                        response: ChangeState.Response) -> ChangeState.Response:
        """Run the transition; a transition the state does not have is answered false."""
        label = request.transition.label or TRANSITION_NAMES.get(
            request.transition.id, f'transition {request.transition.id}')
        try:
            return self.change(request, response)
        except _rclpy.RCLError as err:               # not a transition of the present state
            self.failure(f'{label} refused in state {self.state()}: no such transition from '
                         f'it ({str(err).split(",")[0]})')
            response.success = False
            return response
