"""
End to end: a storm of requests never stalls the arm's data.

The sim bridge, the controller and the planner run as processes with their shipped parameter
files (``state_timeout`` 0.25 s, /joint_states at 100 Hz moving, 20 Hz at rest). Each node in
turn gets ``STORM`` seconds of requests, ``IN_FLIGHT`` at a time: parameter sets of generated
hostile values (``hostile_messages``: wrong types, non-finite, 100,000-element lists; only
values the package's table refuses: a storm of valid values would change what the nodes do, as
it should), gets and describes, and a flood of generated messages on one of its topics; each
storm starts with a motion of the arm (about 2 s; then it rests). Meanwhile an independent
reader takes every /joint_states. Asserted: the largest gap between two /joint_states stays
under ``STATES_GAP``, the controller's ``max_tick_gap`` under ``TICK_GAP`` and its
``max_states_age`` under ``STATES_AGE``, and it never faults. The figures are printed
(``./run.sh test -m e2e -k storm -rA``).
"""

import time

from hostile_messages import HostileMessages, message_class
from mover6_control.control.status import StatusKey
from mover6_control.errors import InvalidInputError
from mover6_control.nodes.messages.demand_messages import make_demands
from mover6_control.parameters import check_value, NODES
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_testing import ready_client, Stack, wait_until
from sensor_msgs.msg import JointState

pytestmark = pytest.mark.e2e

STORM = 6.0               # [s] of requests per node
IN_FLIGHT = 16            # requests waiting for their answer at a time
# [s] /joint_states come every 10 ms moving, 50 ms at rest; the controller faults when its
# newest is older than its shipped ``state_timeout``: the largest gap the reader sees and the
# controller's own ``max_states_age`` stay under it.
STATES_GAP = STATES_AGE = NODES['controller']['state_timeout'].default
TICK_GAP = 0.1            # [s] ten ticks
FLOODED = {'sim_bridge': '/sim_bridge/reset_to', 'controller': '/controller/delta_joint_cmds',
           'planner': '/pose_goal'}
KINDS = ('double', 'int64', 'boolean', 'string', 'sequence<double>', 'sequence<string>')


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start the three nodes with their shipped parameter files."""
    with Stack(tmp_path_factory.mktemp('storm_logs')) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a goal client once every node answers."""
    with ready_client(stack, lambda: GoalClient(name='storm_client'), timeout=60.0) as node:
        yield node


class States:
    """Every /joint_states arrival (monotonic time), from a reliable reader of its own."""

    def __init__(self, node):
        self.times = []
        node.create_subscription(JointState, '/joint_states',
                                 lambda _: self.times.append(time.monotonic()),
                                 QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))

    def largest_gap(self, start, end):
        """Return the largest gap [s] between arrivals in [start, end]."""
        t = [x for x in self.times if start <= x <= end]
        return float(np.max(np.diff(t))) if len(t) > 1 else float('inf')


def invalid(stream, spec):
    """Return a generated value the package's table refuses for ``spec`` (a hostile set)."""
    while True:
        value = stream.value(stream.rng.choice(KINDS))
        value = value if isinstance(value, (str, bool, int, float)) else list(value)
        try:
            check_value(spec, value)
        except InvalidInputError:
            return value


def storm(client, node_name, seconds, stream):
    """Send ``seconds`` of requests to ``node_name``; return how many were answered."""
    params = AsyncParameterClient(client, node_name)
    assert params.wait_for_services(timeout_sec=20.0)
    listed = params.list_parameters()
    assert wait_until(listed.done, 20.0, lambda t: rclpy.spin_once(client, timeout_sec=t))
    names = [n for n in listed.result().result.names if n in NODES[node_name]]
    topic = FLOODED[node_name]
    types = dict(client.get_topic_names_and_types())
    cls = message_class(types[topic][0])
    flood = client.create_publisher(cls, topic, 10)
    pending, answered = [], 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        while len(pending) < IN_FLIGHT:
            k = stream.rng.randrange(4)
            name = stream.rng.choice(names)
            if k == 0:
                pending.append(params.get_parameters([name]))
            elif k == 1:
                pending.append(params.describe_parameters(names))
            else:
                pending.append(params.set_parameters([Parameter(name, value=invalid(
                    stream, NODES[node_name][name]))]))
        flood.publish(stream.message(cls))
        rclpy.spin_once(client, timeout_sec=0.002)
        answered += sum(f.done() for f in pending)
        pending = [f for f in pending if not f.done()]
    client.destroy_publisher(flood)
    return answered


def test_a_storm_of_requests_never_stalls_the_states_or_the_tick(stack, client):
    states = States(client)
    faults = []
    client.create_subscription(
        type(client.controller_status), 'controller/status',
        lambda msg: faults.append(msg.message) if client.values(msg).get(
            StatusKey.STATE) == 'fault' else None, 10)
    lines = []
    for k, node_name in enumerate(('sim_bridge', 'controller', 'planner')):
        # The arm moves as the storm starts: /joint_states at the full rate, then at rest.
        target = np.full(6, 0.3 if k % 2 == 0 else -0.3)
        client.demands_pub.publish(make_demands(np.atleast_2d(target)))
        start = time.monotonic()
        answered = storm(client, node_name, STORM, HostileMessages(k))
        end = time.monotonic()
        gap = states.largest_gap(start, end)
        lines.append(f'{node_name}: {answered} requests answered in {end - start:.1f} s, '
                     f'largest /joint_states gap {gap * 1e3:.1f} ms')
    assert client.spin_until(lambda: client.controller_status is not None, 5.0)
    values = client.values(client.controller_status)
    tick_gap = float(values[StatusKey.MAX_TICK_GAP])
    states_age = float(values[StatusKey.MAX_STATES_AGE])
    lines.append(f'controller: max_tick_gap {tick_gap * 1e3:.1f} ms, max_states_age '
                 f'{states_age * 1e3:.1f} ms, faults {len(faults)}')
    report = '\n'.join(lines)
    print(report)
    assert all(n.alive() for n in stack.nodes.values()), stack.report()
    assert faults == [], f'{faults[:3]}\n{report}'
    for line in lines[:3]:
        gap = float(line.rsplit('gap ', 1)[1].split(' ')[0]) * 1e-3
        assert gap < STATES_GAP, report
    assert tick_gap < TICK_GAP and states_age < STATES_AGE, report
