"""The controller node with real rclpy in one process; a test node plays the arm."""

import os
import time

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.nodes.controller.demand_thread import WORKER_POINTS
from mover6_control.nodes.controller.node import ControllerNode
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.runtime import local_dds
from mover6_control.parameters import PROFILES
from mover6_control.realtime import steady_interpreter
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
import ros_testing
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
from std_srvs.srv import Trigger

NAMES = [f'joint{i}' for i in range(1, 7)]
# Our own namespace: another run of these tests (same domain) must not cross-talk with this one.
NS = f'controller_test_{os.getpid()}'
# The nodes here run in the test process: a real-time tick (tick_priority, 50 by default) raises
# every thread of it, so most run at normal scheduling; the one test of the tick's timing runs
# the shipped priority (test/node/conftest.py puts the process back after each test).
NORMAL = Parameter('tick_priority', value=0)
GOAL = np.array([0.3, -0.2, 0.2, 0.1, -0.1, 0.3])


class FakeArm(Node):
    """Integrate the commanded JointJog and publish /joint_states; record what comes back."""

    def __init__(self, context, namespace=NS, jog_depth=10):
        super().__init__('fake_arm', context=context, namespace=namespace)
        self.q = np.zeros(6)
        self.qd = np.zeros(6)
        self.publishing = True
        self.names = list(NAMES)
        self.jogs = []
        self.statuses = []
        self.last = time.monotonic()
        self.state_pub = self.create_publisher(JointState, 'joint_states', 10)
        self.demand_pub = self.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.create_subscription(JointJog, 'JointJog', self.on_jog, jog_depth)
        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(DiagnosticStatus, 'controller/status', self.statuses.append, qos)
        self.create_timer(0.02, self.on_timer)
        self.stop_client = self.create_client(Trigger, 'controller/stop')

    def on_jog(self, msg):
        jog = conversions.joint_jog_from_msg(msg)
        names, velocities = list(jog.names), np.array(jog.velocities)
        assert names == NAMES
        self.jogs.append(msg)
        self.qd = velocities

    def on_timer(self):
        now = time.monotonic()
        self.q = self.q + self.qd * min(now - self.last, 0.05)
        self.last = now
        if self.publishing:
            self.state_pub.publish(conversions.make_joint_state(self.names, self.q, self.qd))

    def status(self):
        return conversions.status_values(self.statuses[-1]) if self.statuses else {}

    def next_motion(self):
        """Return the motion id the next accepted demand gets (as the status writes it)."""
        return str(int(self.status().get('motion_id', 0)) + 1)


def start_controller(namespace, parameters):
    """Return a controller node in ``namespace``, a ``FakeArm``, ``spin_until`` and a closer."""
    # conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID;
    # inside ./run.sh test's private network namespace, the local configuration (local_dds).
    assert (os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
            or local_dds.requested())
    context = rclpy.Context()
    rclpy.init(context=context)
    controller = ControllerNode(context=context, namespace=namespace,
                                parameter_overrides=parameters + [NORMAL])
    arm = FakeArm(context, namespace=namespace)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(arm)

    def spin_until(predicate, timeout=30.0):
        if ros_testing.spin_until(executor, predicate, timeout) is None:
            raise AssertionError(f'timed out; last status {arm.status()}')
        return True

    def close():
        executor.shutdown()
        controller.destroy_node()
        arm.destroy_node()
        rclpy.try_shutdown(context=context)
    return controller, arm, spin_until, close


@pytest.fixture(scope='module')
def ros():
    controller, arm, spin_until, close = start_controller(NS, [
        Parameter('profile', value='trapezoidal'), Parameter('rate', value=100.0)])
    yield controller, arm, spin_until
    close()


def test_arrives_and_reports(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    motion = arm.next_motion()
    arm.demand_pub.publish(demand_messages.make_demands(np.array([GOAL / 2, GOAL])))
    # 'arrived' comes inside goal_tolerance; the controller then settles (settle_tolerance,
    # at most settle_time) and goes idle holding a zero command.
    spin_until(lambda: arm.status().get('motion_id') == motion
               and arm.status().get('result') == 'arrived'
               and arm.status().get('state') == 'idle')
    status = arm.statuses[-1]
    assert conversions.status_level_name(status) == 'OK'
    values = conversions.status_values(status)
    assert values['state'] == 'idle' and values['waypoints'] == '2'
    assert float(values['final_joint_error']) <= 0.002
    np.testing.assert_allclose(arm.q, GOAL, atol=0.01)
    last = arm.jogs[-1]
    assert list(last.velocities) == [0.0] * 6          # explicit zero on arrival
    assert last.header.stamp.sec > 0 or last.header.stamp.nanosec > 0
    seen = {conversions.status_values(s)['state'] for s in arm.statuses}
    assert {'executing', 'idle'} <= seen


def jog_period(arm, spin_until, count=50):
    """Return the mean time [s] between the next ``count`` JointJog commands."""
    start = len(arm.jogs)
    spin_until(lambda: len(arm.jogs) > start)
    first, t0 = len(arm.jogs), time.monotonic()
    spin_until(lambda: len(arm.jogs) >= first + count)
    return (time.monotonic() - t0) / (len(arm.jogs) - first)


def test_rate_is_about_the_parameter(ros):
    controller, arm, spin_until = ros
    period = jog_period(arm, spin_until)          # rate 100 Hz
    assert 1 / 130 <= period <= 1 / 50, period


def test_parameter_service_refuses_bad_values_and_describes_ranges(ros):
    """
    Parameter services: a bad value is refused with a reason and changes nothing.

    As ``ros2 param set`` would set it; and the descriptors carry the ranges and allowed values,
    as ``ros2 param describe`` shows them.
    """
    from rclpy.parameter_client import AsyncParameterClient
    controller, arm, spin_until = ros
    client = AsyncParameterClient(arm, 'controller')
    spin_until(client.services_are_ready)

    def set_remotely(name, value):
        future = client.set_parameters([Parameter(name, value=value)])
        spin_until(future.done)
        return future.result().results[0]

    for name, value, words in (
            ('rate', -5.0, 'rate'), ('rate', 100, 'type'),
            ('profile', 'banana', 'one of: synchronised, trapezoidal'),
            ('driver_tick_size', [0.001, -0.001, 0.001, 0.001, 0.001, 0.001], 'each value'),
            ('limit_set', 'hardware', 'read-only')):
        result = set_remotely(name, value)
        assert not result.successful, (name, value)
        assert words in result.reason, result.reason
    assert controller.get_parameter('rate').value == 100.0
    assert controller.get_parameter('profile').value == 'trapezoidal'
    assert controller.get_parameter('limit_set').value == 'within_90_deg'
    assert len(controller.get_parameter('driver_tick_size').value) == 6
    assert controller.core.config.rate == 100.0

    future = client.describe_parameters(['rate', 'profile', 'jog_units'])
    spin_until(future.done)
    rate, profile, jog_units = future.result().descriptors
    span = rate.floating_point_range[0]
    assert (span.from_value, span.to_value) == (1.0, 1000.0)
    assert rate.description.endswith('[Hz]')
    assert profile.additional_constraints == 'one of: ' + ', '.join(PROFILES)
    assert jog_units.additional_constraints == 'one of: rad_per_s, fraction_of_max'
    assert not rate.read_only


def test_bad_start_parameters_stop_the_controller():
    """A value refused at run time is refused at start, saying why (a ValueError)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(ValueError, match='rate'):
            ControllerNode(context=context, namespace=NS + '_bad',
                           parameter_overrides=[Parameter('rate', value=-5.0)])
    finally:
        rclpy.try_shutdown(context=context)


def test_flat_and_bad_demands(ros):
    controller, arm, spin_until = ros
    bad = Float32MultiArray(data=[0.1] * 7)
    arm.demand_pub.publish(bad)
    spin_until(lambda: 'multiple of 6' in arm.status().get('rejected', ''))
    outside = Float32MultiArray(data=[0.0, 0.0, 0.0, 0.0, 0.0, 3.0])
    arm.demand_pub.publish(outside)
    spin_until(lambda: 'joint6' in arm.status().get('rejected', ''))
    flat = Float32MultiArray(data=[float(x) for x in np.zeros(6)])
    motion = arm.next_motion()
    arm.demand_pub.publish(flat)
    spin_until(lambda: arm.status().get('motion_id') == motion
               and arm.status().get('result') == 'arrived')


def test_stop_service_decelerates_and_holds(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    motion = arm.next_motion()
    arm.demand_pub.publish(demand_messages.make_demands(GOAL[None]))
    spin_until(lambda: arm.status().get('motion_id') == motion
               and arm.status().get('state') == 'executing')
    spin_until(lambda: np.max(np.abs(arm.qd)) > 0.1)
    future = arm.stop_client.call_async(Trigger.Request())
    spin_until(future.done)
    assert future.result().success
    spin_until(lambda: arm.status().get('result') == 'stopped'
               and arm.status().get('state') == 'idle')
    assert list(arm.jogs[-1].velocities) == [0.0] * 6


def test_stale_and_incomplete_states_fault_then_recover(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    motion = arm.next_motion()
    arm.demand_pub.publish(demand_messages.make_demands(GOAL[None] if np.max(np.abs(
        arm.q - GOAL)) > 0.2 else -GOAL[None]))       # somewhere the arm must move to
    spin_until(lambda: arm.status().get('motion_id') == motion
               and np.max(np.abs(arm.qd)) > 0.05)
    arm.publishing = False
    spin_until(lambda: arm.status().get('state') == 'fault')
    assert conversions.status_level_name(arm.statuses[-1]) == 'ERROR'
    assert arm.status().get('result') == 'fault'
    spin_until(lambda: not np.any(arm.qd))
    arm.publishing = True
    spin_until(lambda: arm.status().get('state') == 'idle')
    arm.names = NAMES[:5] + ['gripper']                   # joint6 missing
    spin_until(lambda: arm.status().get('state') == 'fault')
    assert 'joint6' in arm.statuses[-1].message
    arm.names = list(NAMES)
    spin_until(lambda: arm.status().get('state') == 'idle')


def test_ticks_follow_sim_time():
    """With use_sim_time the ticks run on /clock: stamps in sim time, none while it stands."""
    context = rclpy.Context()
    rclpy.init(context=context)     # the run's own domain (conftest.py): /clock is global
    controller = ControllerNode(context=context, namespace=NS + '_sim', parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('rate', value=100.0), NORMAL])
    clock_node = Node('fake_clock', context=context, namespace=NS + '_sim')
    clock_pub = clock_node.create_publisher(Clock, '/clock', 10)
    stamps, sim = [], {'ns': 1000 * 10**9, 'running': True}
    clock_node.create_subscription(
        JointJog, 'JointJog',
        lambda m: stamps.append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9), 10)

    def advance():
        if sim['running']:
            sim['ns'] += 5 * 10**6                         # 5 ms of sim time per 10 ms of wall
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(sim['ns'], 10**9)
        clock_pub.publish(msg)

    clock_node.create_timer(0.01, advance)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(clock_node)

    def spin_until(predicate, timeout=30.0):
        if ros_testing.spin_until(executor, predicate, timeout) is None:
            raise AssertionError(f'timed out with {len(stamps)} ticks')

    try:
        spin_until(lambda: len(stamps) >= 60)
        recent = np.array(stamps[-50:])
        assert np.all(recent > 1000.0)                     # stamped in sim time
        np.testing.assert_allclose(np.median(np.diff(recent)), 0.01, atol=1e-3)
        sim['running'] = False                             # the simulation pauses
        paused_at = sim['ns'] * 1e-9
        t_pause = time.monotonic()
        spin_until(lambda: time.monotonic() - t_pause > 0.8)
        # No tick is stamped after sim time stopped (judged by stamp, not by arrival: ticks
        # published before the pause can still be in the queue on a loaded machine).
        assert max(stamps) <= paused_at + 0.01 + 1e-9
        # Nor does it keep publishing at the frozen time.
        assert sum(1 for t in stamps if t >= paused_at - 0.005) <= 2
    finally:
        executor.shutdown()
        controller.destroy_node()
        clock_node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_a_blocked_publish_holds_up_neither_states_nor_status(ros):
    """A JointJog write that blocks (DDS, seen for 0.33 s at start-up) stalls only the tick."""
    controller, arm, spin_until = ros
    seen = len(arm.statuses)                   # fresh status: other tests may have paused us
    spin_until(lambda: len(arm.statuses) > seen + 1 and arm.status().get('state') == 'idle')
    publish, blocked = controller.jog.publisher.publish, []

    def blocking_publish(msg):
        if not blocked:
            blocked.append(len(arm.jogs))
            time.sleep(0.4)                        # the blocked write: longer than state_timeout
            blocked.append(True)                   # (0.25 s), in the tick thread
        publish(msg)

    seen = len(arm.statuses)
    controller.jog.publisher.publish = blocking_publish
    try:
        # Fifty ticks after the blocked one: a fault it caused would have been published.
        spin_until(lambda: len(blocked) == 2 and len(arm.jogs) > blocked[0] + 50)
    finally:
        del controller.jog.publisher.publish
    # The states that came meanwhile were taken, so the late tick found them fresh: no fault.
    states = [conversions.status_values(s)['state'] for s in arm.statuses[seen:]]
    assert 'fault' not in states and states[-1] == 'idle', [s.message for s in arm.statuses[seen:]]
    assert float(arm.status()['max_tick_gap']) >= 0.4


def labelled(label):
    """Return a one-row demand to GOAL whose first dimension is labelled ``label``."""
    msg = demand_messages.make_demands(GOAL[None])
    msg.layout.dim[0].label = label
    return msg


def test_node_times_a_demand_by_its_profile_without_touching_the_parameter(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    arm.demand_pub.publish(labelled('waypoints goal typed-1 profile quintic'))
    spin_until(lambda: arm.status().get('goal_id') == 'typed-1'
               and arm.status().get('result') == 'arrived')
    assert arm.status()['motion_profile'] == 'quintic'
    assert arm.status()['profile'] == 'trapezoidal'
    assert controller.get_parameter('profile').value == 'trapezoidal'
    spin_until(lambda: arm.status().get('state') == 'idle')


def test_node_refuses_an_unknown_profile_with_the_reason(ros):
    controller, arm, spin_until = ros
    spin_until(lambda: arm.status().get('state') == 'idle')
    arm.demand_pub.publish(labelled('waypoints goal typed-2 profile banana'))
    spin_until(lambda: arm.status().get('rejected_goal_id') == 'typed-2')
    assert 'banana' in arm.status()['rejected']
    assert controller.get_parameter('profile').value == 'trapezoidal'


def test_parameters_apply_live(ros):
    """
    A valid set applies at once when idle, after the running motion during one.

    An invalid whole config is refused with its reason and changes nothing; a read-only
    parameter is refused.
    """
    from rclpy.parameter_client import AsyncParameterClient
    controller, arm, spin_until = ros
    client = AsyncParameterClient(arm, 'controller')
    spin_until(client.services_are_ready)

    def set_remotely(**values):
        future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        spin_until(future.done)
        return future.result().results[0]

    spin_until(lambda: arm.status().get('state') == 'idle')
    assert set_remotely(profile='synchronised').successful
    spin_until(lambda: arm.status().get('profile') == 'synchronised')
    assert 'pending_parameters' not in arm.status()
    motion = int(arm.status()['motion_id']) + 1
    arm.demand_pub.publish(demand_messages.make_demands(np.array([np.zeros(6), GOAL])))
    spin_until(lambda: arm.status().get('motion_id') == str(motion)
               and arm.status().get('state') == 'executing')
    assert 'synchronised' in arm.statuses[-1].message

    assert set_remotely(profile='trapezoidal', goal_tolerance=0.003).successful
    spin_until(lambda: 'pending_parameters' in arm.status())
    assert arm.status()['profile'] == 'synchronised'
    assert 'profile trapezoidal' in arm.status()['pending_parameters']
    spin_until(lambda: arm.status().get('state') == 'idle')
    spin_until(lambda: arm.status().get('profile') == 'trapezoidal'
               and 'pending_parameters' not in arm.status())
    assert arm.status()['goal_tolerance'].split() == ['0.003000'] * 6

    # Valid alone, not with the t_max in force: the ramps would be longer than the move.
    result = set_remotely(t_blend=0.8)
    assert not result.successful and 't_blend' in result.reason, result.reason
    assert controller.get_parameter('t_blend').value == 0.0
    assert controller.core.config.law.t_blend == 0.0
    result = set_remotely(jog_units='fraction_of_max')
    assert not result.successful and 'read-only' in result.reason, result.reason
    assert controller.core.config.jog_units == 'rad_per_s'
    assert set_remotely(rate=50.0, profile='trapezoidal', goal_tolerance=0.002).successful
    spin_until(lambda: arm.status().get('rate') == '50')
    period = jog_period(arm, spin_until, 25)
    assert 1 / 70 <= period <= 1 / 25, period
    assert set_remotely(rate=100.0).successful


def test_destroying_the_node_sends_a_zero_command():
    """The node goes away mid-motion and leaves a zero command (a node of its own)."""
    controller, arm, spin_until, close = start_controller(NS + '_destroyed', [
        Parameter('profile', value='trapezoidal'), Parameter('rate', value=100.0)])
    try:
        spin_until(lambda: arm.status().get('state') == 'idle')
        arm.demand_pub.publish(demand_messages.make_demands((-GOAL)[None]))
        spin_until(lambda: arm.status().get('motion_id') == '1'
                   and np.max(np.abs(arm.qd)) > 0.05)
        count = len(arm.jogs)
        controller.destroy_node()
        spin_until(lambda: len(arm.jogs) > count and not np.any(arm.qd))
        assert list(arm.jogs[-1].velocities) == [0.0] * 6
    finally:
        close()


def wavy_path(start, goal, n=100):
    """Return n waypoints (n, 6) from near ``start`` to ``goal`` that bend all the way."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return start + s * (goal - start) + 0.05 * np.sin(4.0 * np.pi * s) * np.array(
        [1.0, -1.0, 1.0, -1.0, 1.0, -1.0])


def test_continuous_demands_never_stall_the_ticks():
    """
    Long continuous demands, one replacing a running motion: no tick is late.

    The largest demand the controller plans in its own process (``WORKER_POINTS`` - 1
    waypoints; larger ones go to its planning process) takes the continuous law about 15 ms of
    CPU (more on a loaded machine) in the demand thread, while the executor also serves the
    fake arm; the tick thread must go on at its period meanwhile. Judged by the node's own
    ``max_tick_gap`` and by the stamps of the JointJog commands (taken by the tick thread; a
    deep queue so none is dropped).
    """
    undo = steady_interpreter()                   # as the controller's main() starts
    context = rclpy.Context()
    rclpy.init(context=context)
    ns = NS + '_continuous'
    # The shipped tick_priority (the node tier's conftest puts the process back after).
    controller = ControllerNode(context=context, namespace=ns, parameter_overrides=[
        Parameter('profile', value='continuous'), Parameter('rate', value=100.0)])
    arm = FakeArm(context, namespace=ns, jog_depth=1000)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(arm)

    def spin_until(predicate, timeout=30.0):
        held = ros_testing.spin_until(executor, predicate, timeout)
        if held is None:
            raise AssertionError(f'timed out; last status {arm.status()}')
        return held

    def stamp(msg):
        return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    try:
        spin_until(lambda: arm.status().get('state') == 'idle')
        first = len(arm.jogs)
        taken = []
        for motion, (start, goal) in enumerate([(np.zeros(6), GOAL), (GOAL / 2, -GOAL / 2)], 1):
            sent = time.monotonic()
            arm.demand_pub.publish(demand_messages.make_demands(
                wavy_path(start, goal, WORKER_POINTS - 1)))
            taken.append(spin_until(lambda: arm.status().get('motion_id') == str(motion)
                                    and arm.status().get('state') == 'executing') - sent)
            if motion == 1:                       # the second replaces the running first
                spin_until(lambda: np.max(np.abs(arm.qd)) > 0.2)
        spin_until(lambda: arm.status().get('motion_id') == '2'
                   and arm.status().get('result') == 'arrived')
        np.testing.assert_allclose(arm.q, -GOAL / 2, atol=0.01)
        gaps = np.diff([stamp(m) for m in arm.jogs[first:]])
        assert len(gaps) > 100 and np.min(gaps) > 0.0
        assert np.max(gaps) < 0.05, f'JointJog stamps {np.max(gaps) * 1e3:.0f} ms apart'
        assert float(arm.status()['max_tick_gap']) < 0.05, arm.status()
        assert float(arm.status()['max_tick_gap']) >= np.max(gaps) - 5e-5   # 0.1 ms digits
        assert max(taken) < 2.0, taken            # a stalled node took demands seconds late
    finally:
        undo()
        executor.shutdown()
        controller.destroy_node()
        arm.destroy_node()
        rclpy.try_shutdown(context=context)


def test_a_demand_before_the_first_states_waits_for_them():
    """
    Issue 21: a demand that comes before the first /joint_states is taken once they come.

    (The planner can be quicker at start-up: the demand was refused, 'cannot take a demand
    while waiting_for_states'.) The wait is bounded: DEMAND_STATE_WAIT, then it is refused.
    """
    context = rclpy.Context()
    rclpy.init(context=context)
    namespace = f'{NS}_early'
    controller = ControllerNode(context=context, namespace=namespace,
                                parameter_overrides=[NORMAL])
    arm = FakeArm(context, namespace=namespace)
    arm.publishing = False
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(arm)

    def spin_until(predicate, timeout=30.0):
        return ros_testing.spin_until(executor, predicate, timeout) is not None
    try:
        assert spin_until(lambda: arm.demand_pub.get_subscription_count() > 0
                          and arm.status().get('state') == 'waiting_for_states')
        arm.demand_pub.publish(demand_messages.make_demands(GOAL[None], 'early-1'))
        # Taken off the queue.
        assert spin_until(lambda: controller.demand_thread.jobs.empty(), 10.0)
        spin_until(lambda: 'rejected' in arm.status(), 0.2)
        assert 'rejected' not in arm.status(), arm.status()
        arm.publishing = True
        assert spin_until(lambda: arm.status().get('goal_id') == 'early-1'), arm.status()
        assert 'rejected' not in arm.status(), arm.status()
        # A demand when no states come at all is refused after the wait, with the reason.
        arm.publishing = False
        assert spin_until(lambda: arm.status().get('state') == 'fault')
        arm.demand_pub.publish(demand_messages.make_demands(GOAL[None] / 2, 'early-2'))
        assert spin_until(lambda: arm.status().get('rejected_goal_id') == 'early-2')
        assert 'cannot take a demand while fault' in arm.status()['rejected']
        # A fault that clears while a demand waits for valid states: the demand is taken (the
        # refusal named a fault that cleared a moment later; issue 21, item 6).
        arm.demand_pub.publish(demand_messages.make_demands(GOAL[None] / 3, 'early-3'))
        assert spin_until(lambda: controller.demand_thread.jobs.empty(), 10.0)   # taken
        arm.publishing = True
        assert spin_until(lambda: arm.status().get('goal_id') == 'early-3'), arm.status()
        assert 'rejected' not in arm.status(), arm.status()      # taken: refusals cleared
    finally:
        executor.shutdown()
        controller.destroy_node()
        arm.destroy_node()
        rclpy.try_shutdown(context=context)
