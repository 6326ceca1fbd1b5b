"""
``ros2 lifecycle get|set`` for a test: the same service calls and the same output as ros2cli's.

The ROS 2 wheels this package runs on (requirements/ros.txt) carry no ros2cli, and neither PyPI
nor Debian has it; this stand-in makes exactly the calls of ros2lifecycle's ``get`` and ``set``
verbs (``<node>/get_state``; ``<node>/get_available_transitions``, the transition picked by
label or id, ``<node>/change_state``) and prints what they print, so a test runs it as a user
runs ``ros2 lifecycle``: a process of its own, talking to the node over DDS.

    python test/lifecycle_cli.py get /driver
    python test/lifecycle_cli.py set /driver activate
"""

import sys

from lifecycle_msgs.srv import ChangeState, GetAvailableTransitions, GetState
import rclpy
from rclpy.node import Node

TIMEOUT = 120.0        # [s] per call (an activation references the arm)


def call(node, srv_type, name, request):
    """Call service ``name`` once it is there; return the response (or raise TimeoutError)."""
    client = node.create_client(srv_type, name)
    if not client.wait_for_service(timeout_sec=30.0):
        raise TimeoutError(f'service {name} not available')
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=TIMEOUT)
    if not future.done():
        raise TimeoutError(f'no answer from {name} within {TIMEOUT} s')
    return future.result()


def get(node, name):
    """Print the node's state as ``ros2 lifecycle get`` does: 'label [id]'."""
    state = call(node, GetState, f'{name}/get_state', GetState.Request()).current_state
    print(f'{state.label} [{state.id}]')
    return 0


def set_(node, name, wanted):
    """Trigger a transition as ``ros2 lifecycle set`` does; return its exit code."""
    transitions = call(node, GetAvailableTransitions, f'{name}/get_available_transitions',
                       GetAvailableTransitions.Request()).available_transitions
    chosen = [t.transition for t in transitions if t.transition.label == wanted] or \
        [t.transition for t in transitions if str(t.transition.id) == wanted]
    if not chosen:
        print('Unknown transition requested, available ones are:' + ''.join(
            f'\n- {t.transition.label} [{t.transition.id}]' for t in transitions),
            file=sys.stderr)
        return 1
    request = ChangeState.Request()
    request.transition = chosen[0]
    if call(node, ChangeState, f'{name}/change_state', request).success:
        print('Transitioning successful')
    else:
        print('Transitioning failed', file=sys.stderr)
    return 0


def main(argv):
    """Run ``get NODE`` or ``set NODE TRANSITION``; return the exit code."""
    rclpy.init()
    node = Node('lifecycle_cli')
    try:
        if argv[:1] == ['get'] and len(argv) == 2:
            return get(node, argv[1])
        if argv[:1] == ['set'] and len(argv) == 3:
            return set_(node, argv[1], argv[2])
        print('usage: lifecycle_cli.py get NODE | set NODE TRANSITION', file=sys.stderr)
        return 2
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
