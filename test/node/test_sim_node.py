"""
The sim_bridge node on real rclpy (Fast DDS), in one process with a test node.

Every wait is a predicate with a generous limit, never a fixed sleep, except where a test shows
that nothing happens (a pause) and so must watch for a while.
"""

import math
import os
import time

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from control_msgs.msg import JointJog  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from mover6_control.kinematics.arm import mover6  # noqa: E402
from mover6_control.nodes.messages import conversions  # noqa: E402
from mover6_control.nodes.runtime.qos import STATUS_QOS  # noqa: E402
from mover6_control.resources import CONFIG_DIR  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_testing import spin_until  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from sim_bridge.bridge_node import SimBridgeNode, unfitted_joints  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

NAMES = [f'joint{i}' for i in range(1, 7)]
LIMIT = 30.0      # [s] generous limit of every wait


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module (domain 31, localhost only; no display)."""
    os.environ.pop('DISPLAY', None)
    os.environ.pop('WAYLAND_DISPLAY', None)
    rclpy.init()
    yield
    rclpy.try_shutdown()


class Harness:
    """The bridge under test plus a test node that talks to it, on one executor."""

    def __init__(self, **params):
        # physics_priority 0: a real-time physics thread here would raise every thread of the
        # test process (the priority itself: test_physics_priority_*, in a child process).
        params.setdefault('physics_priority', 0)
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        self.bridge = SimBridgeNode(parameter_overrides=overrides)
        self.node = rclpy.create_node('sim_bridge_tester')
        self.states = []
        self.clocks = []
        self.jog_pub = self.node.create_publisher(JointJog, 'JointJog', 10)
        self.reset_to_pub = self.node.create_publisher(JointState, 'sim_bridge/reset_to', 10)
        self.node.create_subscription(JointState, 'joint_states', self.states.append, 100)
        self.node.create_subscription(Clock, 'clock', self.clocks.append, 1000)
        self.clients = {name: self.node.create_client(kind, f'sim_bridge/{name}')
                        for name, kind in (('reset', Trigger), ('pause', SetBool),
                                           ('step', Trigger))}
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.bridge)
        self.executor.add_node(self.node)

    def spin_until(self, predicate, timeout=LIMIT):
        """Spin until ``predicate()`` holds; return whether it did."""
        return spin_until(self.executor, predicate, timeout) is not None

    def stream(self, velocities, period=0.01):
        """Publish a JointJog of ``velocities`` every ``period`` [s] until ``stop_stream``."""
        return self.node.create_timer(period, lambda: self.jog(velocities))

    def stop_stream(self, timer):
        """End a stream ``stream`` started."""
        self.node.destroy_timer(timer)

    def call(self, name, request):
        """Call one of the bridge's services and return the response."""
        client = self.clients[name]
        assert self.spin_until(client.service_is_ready), f'{name} service never came up'
        future = client.call_async(request)
        assert self.spin_until(future.done), f'{name} call not answered'
        return future.result()

    def jog(self, velocities, names=NAMES):
        """Publish one JointJog."""
        msg = JointJog()
        msg.joint_names = list(names)
        msg.velocities = [float(v) for v in velocities]
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self.jog_pub.publish(msg)

    def latest(self):
        """Return (stamp [s], q, qd, effort) of the arm's joints in the newest /joint_states."""
        msg = self.states[-1]
        return (conversions.stamp_to_seconds(msg.header.stamp), arm(msg, 'position'),
                arm(msg, 'velocity'), arm(msg, 'effort'))

    def close(self):
        """Destroy both nodes."""
        self.executor.shutdown()
        self.bridge.destroy_node()
        self.node.destroy_node()


def arm(msg, field):
    """Return the arm's six values of a JointState's ``field``, by name (the gripper follows)."""
    at = [list(msg.name).index(name) for name in NAMES]
    return np.array(getattr(msg, field))[at]


@pytest.fixture
def harness(request):
    """Yield a bridge with the test's parameters (indirect parametrize of ``harness``)."""
    h = Harness(**getattr(request, 'param', {}))
    assert h.spin_until(lambda: len(h.states) > 3), 'no /joint_states from the bridge'
    yield h
    h.close()


def stamp_rate(messages):
    """Return the rate [Hz] of ``messages`` by their header stamps."""
    stamps = [conversions.stamp_to_seconds(m.header.stamp) for m in messages]
    return (len(stamps) - 1) / (stamps[-1] - stamps[0])


def test_joint_states_are_complete_and_at_the_rate(harness):
    """
    Name joint1..joint6 and the gripper, at the moving and the resting rate.

    Position, velocity and effort; 100 Hz while moving, 20 Hz at rest.

    At rest (nothing moves the arm) /joint_states come at ``rest_publish_rate``, as the real
    arm's driver publishes; a JointJog stream that moves the arm brings ``publish_rate`` back,
    and its end (the joints halt when it goes stale) the rest rate; ~/status says which.
    """
    h = harness
    statuses = []
    h.node.create_subscription(DiagnosticStatus, 'sim_bridge/status',
                               lambda m: statuses.append(conversions.status_values(m)),
                               STATUS_QOS)
    start = len(h.states)
    assert h.spin_until(lambda: len(h.states) >= start + 30)
    msg = h.states[-1]
    assert list(msg.name) == NAMES + ['gripper']     # every joint of the URDF
    assert len(msg.position) == len(msg.velocity) == len(msg.effort) == 7
    # No gripper is fitted to the simulated arm: closed and still, whatever the arm does.
    g = list(msg.name).index('gripper')
    assert (msg.position[g], msg.velocity[g], msg.effort[g]) == (0.0, 0.0, 0.0)
    rate = stamp_rate(h.states[start:])
    assert 18.0 < rate < 22.0, rate
    assert h.spin_until(lambda: statuses and statuses[-1]['joint_states_rate'] == '20')
    assert statuses[-1]['at_rest'] == 'true'

    v = [0.3, 0.0, 0.0, 0.0, 0.0, 0.0]
    h.jog(v)
    assert h.spin_until(lambda: abs(arm(h.states[-1], 'velocity')[0] - v[0]) < 1e-3)
    moving = len(h.states)
    stream = h.stream(v)
    assert h.spin_until(lambda: len(h.states) >= moving + 150)     # 1.5 s at 100 Hz
    h.stop_stream(stream)
    assert arm(h.states[moving:][-1], 'velocity')[0] == pytest.approx(v[0], abs=1e-3)
    rate = stamp_rate(h.states[moving:])
    assert 90.0 < rate < 110.0, rate
    assert any(s['at_rest'] == 'false' and s['joint_states_rate'] == '100' for s in statuses)

    # The stream ended: the joints halt when it goes stale, then the rest rate again.
    assert h.spin_until(lambda: abs(arm(h.states[-1], 'velocity')[0]) < 1e-5)
    resting = len(h.states) + 2
    assert h.spin_until(lambda: len(h.states) >= resting + 20)
    rate = stamp_rate(h.states[resting:])
    assert 18.0 < rate < 22.0, rate


def test_status_reports_sim_time_and_the_real_time_factor(harness):
    """~/status once a second: sim time advancing at the real-time factor, the rates."""
    h = harness
    statuses = []
    h.node.create_subscription(DiagnosticStatus, 'sim_bridge/status',
                               lambda m: statuses.append(conversions.status_values(m)),
                               STATUS_QOS)
    assert h.spin_until(lambda: len(statuses) >= 4)
    first, last = statuses[1], statuses[-1]
    sim = float(last['sim_time']) - float(first['sim_time'])
    wall = float(last['wall_time']) - float(first['wall_time'])
    assert 1.5 < wall < 10.0, wall
    assert sim / wall == pytest.approx(1.0, abs=0.02)
    assert float(last['real_time_factor']) == pytest.approx(1.0, abs=0.05)
    assert last['real_time_factor_target'] == '1.0'
    assert last['overruns'] == '0' and last['jog_rejected'] == '0'


def test_jog_moves_at_the_commanded_speed_then_halts_when_stale(harness):
    """A JointJog stream moves the joints at its speed; without it they halt after 0.2 s."""
    h = harness
    v = np.array([0.2, -0.1, 0.15, 0.3, -0.25, 0.5])
    start = len(h.states)
    stream = h.stream(v, 0.02)
    assert h.spin_until(lambda: len(h.states) >= start + 60)     # 0.6 s at 100 Hz
    h.stop_stream(stream)
    _, q_moving, qd_moving, _ = h.latest()
    np.testing.assert_allclose(qd_moving, v, atol=1e-3)
    assert np.all(np.sign(q_moving) == np.sign(v))
    t_last = h.node.get_clock().now().nanoseconds * 1e-9
    timeout = h.bridge.sim.config.command_timeout
    assert h.spin_until(
        lambda: h.latest()[0] > t_last + timeout + 0.1 and np.all(np.abs(h.latest()[2]) < 1e-4))
    # it did not halt early: the last message before the timeout (less jitter) still moved
    before = [m for m in h.states
              if t_last < conversions.stamp_to_seconds(m.header.stamp) < t_last + timeout - 0.05]
    assert before and np.allclose(arm(before[-1], 'velocity'), v, atol=1e-3)
    # and after the timeout (plus delivery and braking: the exact bound of timeout plus one
    # step is shown on the Simulator, where receipt times are known) every message is at rest
    after = [m for m in h.states
             if conversions.stamp_to_seconds(m.header.stamp) > t_last + timeout + 0.1]
    assert after and all(np.all(np.abs(arm(m, 'velocity')) < 1e-2 * np.abs(v)) for m in after)


BAD = [
    (['joint1', 'joint9'], [0.1, 0.1], 'unknown'),
    (['joint1', 'joint2'], [0.1], 'names but'),
    (['joint1'], [float('nan')], 'non-finite'),
    (['joint1'], [float('inf')], 'non-finite'),
    ([], [], 'no joints'),
    (['joint2', 'joint2'], [0.1, 0.1], 'twice'),
]


def test_every_bad_message_is_rejected_and_the_bridge_runs_on(harness):
    """Each kind of bad JointJog is rejected with a reason; states keep coming; good ones work."""
    h = harness
    for k, (names, values, reason) in enumerate(BAD):
        h.jog(values, names)
        assert h.spin_until(lambda: h.bridge.rejections.count == k + 1), (names, values)
        assert reason in h.bridge.rejections.last
    count = len(h.states)
    assert h.spin_until(lambda: len(h.states) > count + 10)
    h.jog([0.3], ['joint1'])
    assert h.spin_until(lambda: h.latest()[2][0] > 0.29)
    assert h.bridge.rejections.count == len(BAD)


def test_speed_above_the_limit_is_clamped(harness):
    """A speed over the joint's limit is clamped to it (and warned about)."""
    h = harness
    limit = h.bridge.arm.velocity_limits[0]
    assert h.spin_until(lambda: (h.jog([5.0], ['joint1']) or True) and
                        abs(h.latest()[2][0] - limit) < 1e-3)


def test_reset_restores_home_and_reset_to_a_given_q(harness):
    """~/reset puts the arm at rest at initial_q; ~/reset_to at the named positions."""
    h = harness
    assert h.spin_until(lambda: (h.jog([0.4, 0.3, 0, 0, 0, 0]) or True) and
                        h.latest()[1][0] > 0.05)
    assert h.spin_until(lambda: h.bridge.sim.is_stale())    # no jog still in flight
    assert h.latest()[1][0] > 0.05
    response = h.call('reset', Trigger.Request())
    assert response.success
    assert h.spin_until(lambda: np.allclose(h.latest()[1], 0.0, atol=1e-9) and
                        np.allclose(h.latest()[2], 0.0, atol=1e-9))
    target = JointState(name=['joint2', 'joint5'], position=[0.5, -0.7])
    h.reset_to_pub.publish(target)
    expected = np.array([0, 0.5, 0, 0, -0.7, 0])
    assert h.spin_until(lambda: np.allclose(h.latest()[1], expected, atol=1e-9))
    h.reset_to_pub.publish(JointState(name=['joint2'], position=[9.0]))   # outside the limits
    count = len(h.states)
    assert h.spin_until(lambda: len(h.states) > count + 20)
    np.testing.assert_allclose(h.latest()[1], expected, atol=1e-9)


@pytest.mark.parametrize('harness', [{'publish_clock': True}], indirect=True)
def test_pause_step_resume_and_clock(harness):
    """Paused, sim time stands; ~/step runs one period; /clock follows every step."""
    h = harness
    assert h.spin_until(lambda: len(h.clocks) > 50)
    clock = np.array([conversions.stamp_to_seconds(c.clock) for c in h.clocks[-50:]])
    np.testing.assert_allclose(np.diff(clock), h.bridge.pacing.dt, atol=1e-9)
    assert not h.call('step', Trigger.Request()).success      # refused while running
    statuses = []
    h.node.create_subscription(DiagnosticStatus, 'sim_bridge/status', statuses.append,
                               STATUS_QOS)
    assert h.call('pause', SetBool.Request(data=True)).success
    t_paused = h.bridge.sim.time
    # The physics thread's rounds go on while paused: two of its statuses (once a second) say
    # so, and sim time stood all the while.
    assert h.spin_until(lambda: sum(s.message.startswith('paused') for s in statuses) >= 2)
    assert h.bridge.sim.time == t_paused
    count = len(h.states)
    response = h.call('step', Trigger.Request())
    assert response.success, response.message
    assert math.isclose(h.bridge.sim.time, t_paused + 0.01, abs_tol=1e-9)
    assert h.spin_until(lambda: len(h.states) == count + 1)
    assert math.isclose(h.latest()[0], h.bridge.sim.time, abs_tol=1e-9)   # sim-time stamps
    assert h.call('pause', SetBool.Request(data=False)).success
    assert h.spin_until(lambda: h.bridge.sim.time > t_paused + 0.2)


@pytest.mark.parametrize('harness', [{'mode': 'vendor_driver', 'publish_clock': True}],
                         indirect=True)
def test_vendor_mode_publishes_at_20_hz_and_holds_the_command(harness):
    """In vendor mode states come every 50 ms of sim time and one command is held."""
    h = harness
    h.jog([0.5, 0, 0, 0, 0, 0])
    start = len(h.states)
    assert h.spin_until(lambda: len(h.states) > start + 30)      # 1.5 s, no renewal
    stamps = np.array([conversions.stamp_to_seconds(m.header.stamp) for m in h.states[start:]])
    np.testing.assert_allclose(np.diff(stamps), 0.05, atol=1e-9)
    speeds = [arm(m, 'velocity')[0] for m in h.states[-10:]]
    expected = 0.5 * h.bridge.arm.velocity_limits[0] * 0.25
    np.testing.assert_allclose(speeds, expected, rtol=1e-3)


@pytest.mark.parametrize('harness', [{'viewer': True}], indirect=True)
def test_viewer_without_a_display_runs_headless(harness):
    """Asked for a viewer with no display, the bridge warns and runs headless."""
    h = harness
    assert h.bridge.physics.viewer is None
    count = len(h.states)
    assert h.spin_until(lambda: len(h.states) > count + 20)


def test_parameter_service_refuses_bad_values_and_describes_ranges(harness):
    """
    Parameter services: a bad value is refused with a reason and changes nothing.

    As ``ros2 param set`` would set it; and the descriptors carry the ranges and allowed values,
    as ``ros2 param describe`` shows them.
    """
    from rclpy.parameter_client import AsyncParameterClient
    h = harness
    client = AsyncParameterClient(h.node, 'sim_bridge')
    assert h.spin_until(client.services_are_ready)

    def set_remotely(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        assert h.spin_until(future.done)
        return future.result().results[0]

    for name, value, words in (('publish_rate', 1000.0, 'publish_rate'),
                               ('real_time_factor', -1.0, 'real_time_factor'),
                               # read-only since parameters apply live (set at start):
                               ('initial_q', [0.0, 4.0, 0.0, 0.0, 0.0, 0.0], 'read-only'),
                               ('kv', 'stiff', 'read-only'),
                               ('mode', 'vendor_driver', 'read-only')):
        result = set_remotely(name, value)
        assert not result.successful, (name, value)
        assert words in result.reason, result.reason
    assert h.bridge.get_parameter('publish_rate').value == 100.0
    assert h.bridge.get_parameter('real_time_factor').value == 1.0
    assert list(h.bridge.get_parameter('initial_q').value) == [0.0] * 6
    assert h.bridge.get_parameter('mode').value == 'rad_per_s'

    future = client.describe_parameters(['publish_rate', 'mode', 'initial_q'])
    assert h.spin_until(future.done)
    publish_rate, mode, initial_q = future.result().descriptors
    span = publish_rate.floating_point_range[0]
    assert (span.from_value, span.to_value) == (0.1, 500.0)
    assert mode.additional_constraints == 'one of: rad_per_s, vendor_driver' and mode.read_only
    assert initial_q.additional_constraints.startswith('each value from -3.14159')
    assert initial_q.description.endswith('[rad]')


def test_publish_rate_set_live_changes_the_rate_of_joint_states(harness):
    """
    ``ros2 param set /sim_bridge rest_publish_rate`` and ``publish_rate`` change the rate at once.

    Set through the parameter service as ``ros2 param set`` does, on an arm at rest; the rate
    is what a subscriber counts over a window of arrivals (wall clock) and of stamps, with
    generous margins. At rest the slower of the two rates holds.
    """
    from rclpy.parameter_client import AsyncParameterClient
    h = harness
    arrivals = []             # (monotonic arrival [s], stamp [s]) of each /joint_states
    h.node.create_subscription(
        JointState, 'joint_states',
        lambda m: arrivals.append((time.monotonic(), conversions.stamp_to_seconds(
            m.header.stamp))), 100)
    client = AsyncParameterClient(h.node, 'sim_bridge')
    assert h.spin_until(client.services_are_ready)

    def rate_after_setting(name, value, count):
        future = client.set_parameters([Parameter(name, value=value)])
        assert h.spin_until(future.done)
        assert future.result().results[0].successful, future.result().results[0].reason
        assert h.bridge.get_parameter(name).value == value
        start = len(arrivals) + 2         # skip what was already in flight
        assert h.spin_until(lambda: len(arrivals) >= start + count), (value, len(arrivals))
        window = np.array(arrivals[start:])
        wall = (len(window) - 1) / (window[-1, 0] - window[0, 0])
        stamped = (len(window) - 1) / (window[-1, 1] - window[0, 1])
        return wall, stamped

    wall, stamped = rate_after_setting('rest_publish_rate', 100.0, 150)
    assert 60.0 < wall < 140.0 and 80.0 < stamped < 120.0, (wall, stamped)
    wall, stamped = rate_after_setting('publish_rate', 20.0, 30)
    assert 12.0 < wall < 30.0 and 15.0 < stamped < 25.0, (wall, stamped)
    wall, stamped = rate_after_setting('publish_rate', 100.0, 150)
    assert 60.0 < wall < 140.0 and 80.0 < stamped < 120.0, (wall, stamped)
    wall, stamped = rate_after_setting('rest_publish_rate', 10.0, 15)
    assert 6.0 < wall < 15.0 and 8.0 < stamped < 12.0, (wall, stamped)


@pytest.mark.parametrize('bad', [{'mode': 'turbo'}, {'publish_rate': 1000.0},
                                 {'limit_set': 'lax'}, {'initial_q': [0.0, 0.0]},
                                 {'real_time_factor': -1.0}])
def test_bad_parameters_are_refused(bad):
    """The node refuses to start on nonsense parameters, saying why."""
    overrides = [Parameter(k, value=v) for k, v in bad.items()]
    with pytest.raises(ValueError):
        SimBridgeNode(parameter_overrides=overrides)


def test_contacts_are_reported_on_their_topic(harness):
    """~/contacts: OK with no contact at home; WARN naming the shapes once the tool is in."""
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.qos import DurabilityPolicy, QoSProfile
    h = harness
    reports = []
    h.node.create_subscription(DiagnosticStatus, 'sim_bridge/contacts', reports.append,
                               QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert h.spin_until(lambda: bool(reports))
    assert reports[-1].level == DiagnosticStatus.OK, reports[-1].message
    assert conversions.status_values(reports[-1])['contact_steps'] == '0'
    # Tool pointing down 80 mm into the table (the table goal of issue 14).
    h.reset_to_pub.publish(JointState(name=['joint2', 'joint3', 'joint5'],
                                      position=[0.78, 0.59, 0.2]))
    assert h.spin_until(lambda: reports[-1].level == DiagnosticStatus.WARN)
    values = conversions.status_values(reports[-1])
    assert values['first_contact'] == 'table-link6_tool'
    assert 'table-link6_tool' in values['touching']
    assert int(values['contact_steps']) > 0


PHYSICS_PRIORITY_CHILD = """
import json, time
import rclpy
from rclpy.parameter import Parameter
from mover6_control.realtime import scheduling_of_thread
from sim_bridge.bridge_node import SimBridgeNode
rclpy.init()
bridge = SimBridgeNode(parameter_overrides=[Parameter('physics_priority', value=20)])
deadline = time.monotonic() + 30.0
tid = bridge.physics.thread.native_id
path = f'/proc/self/task/{tid}/stat'
while time.monotonic() < deadline:
    fields = open(path).read().rsplit(')', 1)[1].split()
    # Fields 40 and 41 of stat (the 38th and 39th after the name): rt_priority, policy.
    if int(fields[37]) != 0 or bridge.physics.failure or bridge.sim.time > 0.1:
        break
    time.sleep(0.01)
print(json.dumps({'rt_priority': int(fields[37]), 'policy': int(fields[38]),
                  'main': scheduling_of_thread(), 'failure': bridge.physics.failure,
                  'stepped': bridge.sim.time > 0.0}))
bridge.destroy_node()
rclpy.try_shutdown()
"""


@pytest.mark.parametrize('right', ['as the run has it', 'taken away'])
def test_physics_priority_raises_the_physics_thread_or_says_why(right):
    """``physics_priority``: the physics thread at SCHED_FIFO, the node's others just below."""
    import json
    import os
    import subprocess
    import sys
    from ros_testing import without_the_right
    # A child process: raising a thread of this process would raise all the test's threads.
    done = subprocess.run([sys.executable, '-c', PHYSICS_PRIORITY_CHILD], capture_output=True,
                          text=True, timeout=120, env=dict(os.environ),
                          preexec_fn=without_the_right if right == 'taken away' else None)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out['failure'] is None
    if right == 'taken away':       # one line says why; the physics runs on, normally
        assert done.stderr.count('physics_priority 20: real-time scheduling refused') == 1, \
            done.stderr
        assert out['rt_priority'] == 0 and out['stepped'], out
    elif 'physics thread at SCHED_FIFO priority 20' in done.stderr:
        assert (out['rt_priority'], out['policy']) == (20, os.SCHED_FIFO)
        assert out['main'] == ['fifo', 19]
    else:
        assert 'physics_priority 20: real-time scheduling refused' in done.stderr, done.stderr
        assert out['rt_priority'] == 0


def test_unfitted_joints_are_the_urdfs_joints_outside_the_chain(tmp_path):
    """The shipped URDF: the gripper at 0 (closed); another URDF: 0 or the nearer limit."""
    arm = mover6()
    assert unfitted_joints(arm, '') == {'gripper': 0.0}
    with open(os.path.join(CONFIG_DIR, 'mover6.urdf')) as f:
        text = f.read()
    assert 'lower="0" upper="0.03"' in text
    other = tmp_path / 'other.urdf'
    other.write_text(text.replace('lower="0" upper="0.03"', 'lower="0.01" upper="0.03"'))
    assert unfitted_joints(arm, str(other)) == {'gripper': 0.01}
