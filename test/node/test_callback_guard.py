"""
The callback guard on real rclpy: a callback that raises is a refused input, the node goes on.

The shipped executor (``EventsExecutor``, as ``shutdown.run_node`` spins every node) ends its
spin with the exception of any callback that raises; through the guard the same callbacks are
refused inputs, counted by source with their code, answered (a service, a parameter set) and
published on ``~/guard``.
"""

import os

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from mover6_control.errors import InvalidInputError  # noqa: E402
from mover6_control.nodes.messages.conversions import status_values  # noqa: E402
from mover6_control.nodes.runtime.callback_guard import CallbackGuard  # noqa: E402
from mover6_control.nodes.runtime.qos import STATUS_READER_QOS  # noqa: E402
import pytest  # noqa: E402
from rcl_interfaces.msg import Parameter as RosParameter, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
import rclpy  # noqa: E402
from rclpy.experimental.events_executor import EventsExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_testing import spin_until  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

LIMIT = 30.0      # [s] generous limit of every wait


@pytest.fixture
def harness():
    """Yield (guarded node, its guard, a test node, the executor)."""
    rclpy.init()
    node = rclpy.create_node('guarded')
    guard = CallbackGuard(node)
    tester = rclpy.create_node('guard_tester')
    executor = EventsExecutor()
    executor.add_node(node)
    executor.add_node(tester)
    yield node, guard, tester, executor
    executor.shutdown()
    node.destroy_node()
    tester.destroy_node()
    rclpy.try_shutdown()


def callback_of(taken):
    """Return a String callback: 'bad' is invalid input, 'bug' a bug, anything else taken."""
    def on_message(msg):
        if msg.data == 'bad':
            raise InvalidInputError('bad is not a word here')
        if msg.data == 'bug':
            raise KeyError('no such key')
        taken.append(msg.data)
    return on_message


def test_a_raising_subscription_callback_is_a_refused_input(harness):
    node, guard, tester, executor = harness
    taken, statuses = [], []
    guard.subscription(String, 'words', callback_of(taken), 10)
    tester.create_subscription(DiagnosticStatus, 'guarded/guard', statuses.append,
                               STATUS_READER_QOS)
    pub = tester.create_publisher(String, 'words', 10)
    assert spin_until(executor, lambda: pub.get_subscription_count() > 0, LIMIT)
    for word in ('bad', 'bug', 'bad', 'good'):
        pub.publish(String(data=word))
    assert spin_until(executor, lambda: taken == ['good'], LIMIT), (taken, guard.values())
    assert guard.refused == {'/words': 3} and guard.failed == 1
    assert guard.last[:2] == ('/words', 'invalid_input')
    # ~/guard says so within a second (transient local: the latest is there).
    assert spin_until(executor, lambda: statuses and status_values(statuses[-1]).get(
        'refused') == '3', LIMIT), [status_values(s) for s in statuses]
    values = status_values(statuses[-1])
    assert values['internal_errors'] == '1' and values['refused /words'] == '3'
    assert values['last_reason'] == 'bad is not a word here'


def test_a_raising_service_answers_with_the_reason(harness):
    node, guard, tester, executor = harness

    def on_call(request, response):
        raise InvalidInputError('not now')
    guard.service(Trigger, '~/act', on_call)
    client = tester.create_client(Trigger, '/guarded/act')
    assert spin_until(executor, client.service_is_ready, LIMIT)
    future = client.call_async(Trigger.Request())
    assert spin_until(executor, future.done, LIMIT)
    assert not future.result().success
    assert future.result().message == 'refused (invalid_input): not now'
    assert guard.refused == {'/guarded/act': 1}


def test_a_raising_parameter_check_refuses_the_set(harness):
    node, guard, tester, executor = harness
    node.declare_parameter('gain', 1.0)

    def check(parameters):
        raise ZeroDivisionError('division by zero')
    guard.set_check(check)
    result = node.set_parameters([Parameter('gain', value=2.0)])[0]
    assert not result.successful
    assert result.reason == 'refused (internal_error): ZeroDivisionError: division by zero'
    assert node.get_parameter('gain').value == 1.0
    assert guard.failed == 1


def test_rclpy_s_own_parameter_service_refuses_an_unknown_type(harness):
    """
    A SetParameters whose value has type 255 raised ValueError in rclpy and ended the node.

    Found by the generated requests of test_e2e_hostile: every node of the stack died of it.
    """
    node, guard, tester, executor = harness
    node.declare_parameter('gain', 1.0)
    client = tester.create_client(SetParameters, '/guarded/set_parameters')
    assert spin_until(executor, client.service_is_ready, LIMIT)
    odd = RosParameter(name='gain', value=ParameterValue(type=255, double_value=2.0))
    future = client.call_async(SetParameters.Request(parameters=[odd, odd]))
    assert spin_until(executor, future.done, LIMIT)
    results = future.result().results
    assert [r.successful for r in results] == [False, False]
    assert results[0].reason.startswith('refused (internal_error): ValueError: 255')
    assert node.get_parameter('gain').value == 1.0
    assert guard.refused == {'/guarded/set_parameters': 1}
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter('gain', value=3.0).to_parameter_msg()]))
    assert spin_until(executor, future.done, LIMIT)
    assert future.result().results[0].successful and node.get_parameter('gain').value == 3.0
