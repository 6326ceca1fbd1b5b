"""
The driver node with real rclpy, on python-can's ``virtual`` bus, against the CAN-level Mover6.

The arm is ``sim_bridge.can_sim.BusServer`` (six simulated motor modules on the MuJoCo arm) on
the same virtual channel, in a thread of this process; a client node plays the controller and
the operator (JointJog, the services, the lifecycle services, /joint_states, /diagnostics).
The node configures itself at start (``enable_on_start`` false: it stays inactive); the tests
walk the lifecycle through its ``change_state`` service, as ``ros2 lifecycle set`` does.
"""

import itertools
import math
import os
import threading
import time

import can
from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticArray
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from mover6_control.hardware.scaling import load_joints
from mover6_control.nodes.driver.jog_intake import JogIntake, JogRefused
from mover6_control.nodes.driver.node import DriverNode, SERVICES
from mover6_control.nodes.messages import conversions
from mover6_control.realtime import steady_interpreter
import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from ros_testing import Spinning, wait_until
from sensor_msgs.msg import JointState
from sim_bridge.can_sim import build_arm, BusServer
from std_srvs.srv import Trigger

NAMES = [f'joint{i}' for i in range(1, 7)]
_, JOINTS = load_joints()
NS = f'driver_test_{os.getpid()}'
RUNS = itertools.count()


class Operator(Node):
    """Publish JointJog, call the driver's services, record what the driver publishes."""

    def __init__(self, context, namespace):
        super().__init__('operator', context=context, namespace=namespace)
        self.states = []
        self.diagnostics = []
        self.jog_pub = self.create_publisher(JointJog, 'JointJog', 10)
        self.create_subscription(JointState, 'joint_states', self.states.append, 10)
        self.create_subscription(DiagnosticArray, 'diagnostics', self.diagnostics.append, 10)
        self.triggers = {k: self.create_client(Trigger, f'driver/{k}') for k in SERVICES}
        self.change_state = self.create_client(ChangeState, 'driver/change_state')
        self.get_state = self.create_client(GetState, 'driver/get_state')

    def call(self, kind, timeout=60.0):
        client = self.triggers[kind]
        assert client.wait_for_service(timeout_sec=timeout)
        future = client.call_async(Trigger.Request())
        assert wait_for(future.done, timeout), f'{kind}: no answer'
        return future.result()

    def transition(self, transition_id, timeout=60.0):
        """Ask the driver to change its state, as ros2 lifecycle set does; return success."""
        assert self.change_state.wait_for_service(timeout_sec=timeout)
        request = ChangeState.Request()
        request.transition.id = transition_id
        future = self.change_state.call_async(request)
        assert wait_for(future.done, timeout), f'transition {transition_id}: no answer'
        return future.result().success

    def lifecycle(self, timeout=10.0):
        """Return the driver's lifecycle state label (as ros2 lifecycle get)."""
        assert self.get_state.wait_for_service(timeout_sec=timeout)
        future = self.get_state.call_async(GetState.Request())
        assert wait_for(future.done, timeout)
        return future.result().current_state.label

    def bus_status(self):
        for msg in reversed(self.diagnostics):
            for status in msg.status:
                if status.name == 'driver: bus':
                    return conversions.status_values(status)
        return {}

    def q(self):
        return list(self.states[-1].position) if self.states else None


def wait_for(predicate, timeout=60.0):
    return wait_until(predicate, timeout, period=0.02)


class Arm:
    """The simulated arm served in a thread; ``lock`` keeps a fault injection between polls."""

    def __init__(self, channel):
        self.arm = build_arm()
        self.modules = self.arm.modules
        self.server = BusServer(self.arm, can.Bus(interface='virtual', channel=channel))
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        while not self.stop.is_set():
            with self.lock:
                self.server.poll(self.arm.sim.config.physics_dt)

    def inject(self, joint, flags, sticky=False):
        with self.lock:
            self.arm.inject_flags(joint, flags, time.monotonic(), sticky)

    def close(self):
        self.stop.set()
        self.thread.join(timeout=10.0)
        self.server.bus.shutdown()


def make_rig(extra=()):
    channel = f'driver_node_{os.getpid()}_{next(RUNS)}'
    namespace = f'{NS}_{next(RUNS)}'
    undo = steady_interpreter()                # as the driver's main() starts
    arm = Arm(channel)
    context = rclpy.Context()
    rclpy.init(context=context)
    # The shipped silent_cycles. No real-time priority here: it would raise every thread of
    # the test process, the simulated modules' too.
    driver = DriverNode(context=context, namespace=namespace, parameter_overrides=[
        Parameter('can_interface', value='virtual'), Parameter('can_channel', value=channel),
        Parameter('cycle_priority', value=0), *extra])
    operator = Operator(context, namespace)
    spinning = Spinning(context, [driver, operator])      # each as its main() spins it

    def close():
        spinning.close()
        driver.destroy_node()
        operator.destroy_node()
        rclpy.try_shutdown(context=context)
        arm.close()
        undo()
    return (driver, operator, arm), close


@pytest.fixture
def rig():
    parts, close = make_rig()
    yield parts
    close()


def activate(operator):
    """Activate the driver (configured at start): reset, enable, reference; wait for it."""
    assert wait_for(lambda: operator.lifecycle() == 'inactive', 30.0)
    assert operator.transition(Transition.TRANSITION_ACTIVATE)
    assert operator.lifecycle() == 'active'
    assert wait_for(lambda: operator.bus_status().get('state') == 'enabled'
                    and operator.bus_status().get('hold') == '')


def jog(operator, velocities, seconds):
    """Publish a JointJog every 20 ms for ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        operator.jog_pub.publish(conversions.make_joint_jog(NAMES, velocities))
        time.sleep(0.02)


def test_states_diagnostics_enable_and_jog(rig):
    driver, operator, arm = rig
    assert wait_for(lambda: operator.states and operator.bus_status())
    assert list(operator.states[-1].name) == NAMES + ['gripper']
    # Until every module has answered the bus reads 'disconnected'; then the modules' power-up
    # state (0x1C, an error until reset) shows.
    assert wait_for(lambda: operator.bus_status().get('state') != 'disconnected')
    assert operator.bus_status()['state'] == 'error', operator.bus_status()  # power-up: 0x1C
    assert 'comm_watchdog' in operator.bus_status()['hold'] or \
        'position_lag' in operator.bus_status()['hold']
    activate(operator)
    assert operator.bus_status()['lifecycle'] == 'active'
    assert [m.referenced for m in arm.modules] == [True] * 4 + [False] * 2
    start = operator.q()
    jog(operator, [0.2, 0, 0, 0, 0, 0], 1.0)
    assert wait_for(lambda: operator.q()[0] - start[0] > 0.05)
    # Commands stop: the arm holds within command_timeout plus a cycle (and the physics). A
    # module starved of the interpreter lock here lags its set-point (up to max_lag) and misses
    # replies (a reading of zero velocity): held is when three readings in a row show no motion
    # and the joint is on its set-point.
    tick = JOINTS[0].tick

    def held_still():
        last = operator.states[-3:]
        report = driver.driver.report
        return len(last) == 3 and all(abs(m.velocity[0]) < 1e-6 for m in last) and \
            abs(last[0].position[0] - last[-1].position[0]) <= tick and \
            report is not None and abs(report.joints[0].lag) <= tick
    assert wait_for(held_still, 10.0)
    held, seen = operator.q()[0], len(operator.states)
    assert wait_for(lambda: len(operator.states) >= seen + 10)     # ten more readings
    assert all(abs(m.position[0] - held) < 1e-3 for m in operator.states[seen:])
    assert all(abs(a - b) < 1e-3 for a, b in zip(operator.q()[1:], start[1:]))


def test_bad_jointjog_is_refused_with_the_reason(rig):
    driver, operator, arm = rig
    assert wait_for(lambda: operator.bus_status())
    bad = [conversions.make_joint_jog(['joint1', 'jointX'], [0.1, 0.1]),
           conversions.make_joint_jog(NAMES, [math.nan] + [0.0] * 5)]
    short = conversions.make_joint_jog(NAMES, [0.1] * 6)
    short.velocities = [0.1] * 5
    for msg in bad + [short]:
        operator.jog_pub.publish(msg)
    assert wait_for(lambda: operator.bus_status().get('jog_refused') == '3')
    assert 'velocities' in operator.bus_status()['last_refusal']
    # The modules' power-up state (an error until reset), once they have all answered: refused
    # JointJogs changed nothing.
    assert wait_for(lambda: driver.driver.report is not None
                    and driver.driver.report.state != 'disconnected')
    assert driver.driver.report.state == 'error', driver.driver.report


def test_set_zero_is_guarded_and_parameters_are_checked(rig):
    driver, operator, arm = rig
    reply = operator.call('set_zero')
    assert not reply.success and 'allow_set_zero' in reply.message
    result = driver.set_parameters([Parameter('speed_override', value=5.0)])[0]
    assert not result.successful and 'speed_override' in result.reason
    result = driver.set_parameters([Parameter('gripper', value='open')])[0]
    assert result.successful
    assert wait_for(lambda: arm.modules[3].digital_out == 0x03)
    reply = operator.call('enable')           # inactive: enabling is the activation's
    assert not reply.success and 'activate it first' in reply.message
    result = driver.set_parameters([Parameter('gripper', value='wide')])[0]
    assert not result.successful


def hostile_jogs():
    """Return (JointJog, the reason it must be refused for) pairs."""
    def jog(names, velocities, **fields):
        msg = conversions.make_joint_jog(names, [0.0] * len(names))
        msg.velocities = velocities
        for name, value in fields.items():
            setattr(msg, name, value)
        return msg
    zeros = [0.0] * 6
    return [
        (JointJog(), 'empty'),
        (jog([], []), 'empty'),
        (jog(NAMES, zeros[:5]), 'length'),
        (jog(NAMES, zeros + [0.0]), 'length'),
        (jog(NAMES[:5], []), 'length'),
        (jog(['joint1', 'joint1'], [0.1, 0.1]), 'names'),
        (jog(['joint1', 'jointX'], [0.1, 0.1]), 'unknown_joint'),
        (jog(['x' * 10000], [0.1]), 'unknown_joint'),
        (jog(NAMES, [math.nan] + zeros[1:]), 'non_finite'),
        (jog(NAMES, [math.inf] + zeros[1:]), 'non_finite'),
        (jog(NAMES, zeros[:5] + [-math.inf]), 'non_finite'),
        (jog(NAMES, [1e30] + zeros[1:]), 'out_of_range'),
        (jog(NAMES, [-1.7e308] + zeros[1:]), 'out_of_range'),
        (jog(NAMES, zeros, displacements=[0.1] * 6), 'displacements'),
    ]


def test_hostile_jointjogs_are_refused_by_reason_and_the_arm_holds(rig):
    driver, operator, arm = rig
    activate(operator)
    start = operator.q()
    cases = hostile_jogs()
    expected = {}
    for i, (msg, reason) in enumerate(cases, start=1):      # one at a time: none lost on DDS
        operator.jog_pub.publish(msg)
        expected[reason] = expected.get(reason, 0) + 1
        line = ', '.join(f'{name} {count}' for name, count in sorted(expected.items()))
        assert wait_for(lambda: operator.bus_status().get('jog_refused') == str(i), 10.0), \
            (reason, operator.bus_status())
        assert operator.bus_status()['jog_refused_by'] == line, operator.bus_status()
    # A flood of valid zero commands: taken (one per cycle counts), the rest superseded.
    flood = conversions.make_joint_jog(NAMES, [0.0] * 6)
    for _ in range(300):
        operator.jog_pub.publish(flood)
    assert wait_for(lambda: int(operator.bus_status().get('jog_superseded', '0')) > 0
                    and operator.bus_status().get('state') == 'enabled')
    # Nothing moved, the node still answers and streams.
    n = len(operator.states)
    assert wait_for(lambda: len(operator.states) > n + 5)
    assert all(abs(a - b) < 1e-3 for a, b in zip(operator.q(), start))
    assert operator.call('enable').success
    # A speed between one and two times the maximum is clipped to it (counted), not refused.
    fast = conversions.make_joint_jog(NAMES, [0.0] * 6)
    fast.velocities = [1.5 * driver.max_speed[0]] + [0.0] * 5
    qd, clipped = driver.intake.jog_velocities(fast)
    assert clipped == 1 and qd[0] == pytest.approx(1.5 * driver.max_speed[0])


def test_the_lifecycle_walked_through_its_service(rig):
    """Configure at start, activate, deactivate, cleanup, configure, shutdown; refusals."""
    driver, operator, arm = rig
    assert wait_for(lambda: operator.lifecycle() == 'inactive', 30.0)
    # Configured: every position read, nothing enabled, nothing moved.
    assert wait_for(lambda: operator.states)
    assert all(not m.enabled for m in arm.modules)
    # Inactive: a valid JointJog is counted, not commanded.
    operator.jog_pub.publish(conversions.make_joint_jog(NAMES, [0.2] * 6))
    assert wait_for(lambda: operator.bus_status().get('jog_ignored') == '1')
    assert 'inactive' in operator.bus_status()['last_ignored']
    # Out of order: the state machine refuses with its reason, the node stays where it was.
    assert not operator.transition(Transition.TRANSITION_CONFIGURE)
    assert operator.lifecycle() == 'inactive'
    assert 'configure refused in state inactive' in driver.last_failure
    activate(operator)
    start = operator.q()
    jog(operator, [0.2] + [0.0] * 5, 0.5)
    assert wait_for(lambda: operator.q()[0] - start[0] > 0.02)
    # Deactivate: the arm comes to rest, every module is disabled.
    assert operator.transition(Transition.TRANSITION_DEACTIVATE)
    assert operator.lifecycle() == 'inactive'
    assert all(not m.enabled for m in arm.modules)
    assert wait_for(lambda: operator.bus_status().get('state') == 'connected')
    # Cleanup: the bus is closed; activate from unconfigured is refused.
    assert operator.transition(Transition.TRANSITION_CLEANUP)
    assert operator.lifecycle() == 'unconfigured' and driver.driver is None
    assert not operator.transition(Transition.TRANSITION_ACTIVATE)
    assert operator.lifecycle() == 'unconfigured'
    reply = operator.call('reset')
    assert not reply.success and 'not configured' in reply.message
    # Configure again (positions read, the reference kept by the modules), then shut down.
    assert operator.transition(Transition.TRANSITION_CONFIGURE)
    assert operator.lifecycle() == 'inactive' and driver.driver is not None
    activate(operator)
    assert operator.transition(Transition.TRANSITION_ACTIVE_SHUTDOWN)
    assert operator.lifecycle() == 'finalized' and driver.driver is None
    assert all(not m.enabled for m in arm.modules)


def test_listen_only_refuses_activation():
    (driver, operator, arm), close = make_rig([Parameter('listen_only', value=True)])
    try:
        assert wait_for(lambda: operator.lifecycle() == 'inactive', 30.0)
        assert not operator.transition(Transition.TRANSITION_ACTIVATE)
        assert operator.lifecycle() == 'inactive'
        assert 'listen_only' in driver.last_failure
        assert all(not m.enabled for m in arm.modules)
    finally:
        close()


def test_power_lost_reads_as_a_state_and_only_recover_brings_the_arm_back(rig):
    driver, operator, arm = rig
    activate(operator)
    for n in range(1, 7):                     # the e-stop: every module browns out, and stays
        arm.inject(n, 0x01, sticky=True)
    assert wait_for(lambda: operator.bus_status().get('state') == 'power_lost', 10.0)
    status = operator.bus_status()
    assert status['hold'].startswith('power lost (e-stop?)') and '~/recover' in status['hold']
    message = [s.message for s in operator.diagnostics[-1].status if s.name == 'driver: bus']
    assert message and message[0].startswith('power lost (e-stop?)'), message
    reply = operator.call('enable')
    assert not reply.success and 'power lost' in reply.message, reply.message
    reply = operator.call('recover')          # the e-stop is still pressed
    assert not reply.success and 'power still lost' in reply.message, reply.message
    with arm.lock:
        for m in arm.modules:                 # the e-stop released
            m.sticky_flags = 0
    reply = operator.call('recover')
    assert reply.success, reply.message
    assert wait_for(lambda: operator.bus_status().get('state') == 'enabled'
                    and operator.bus_status().get('hold') == '', 10.0), operator.bus_status()
    assert [m.referenced for m in arm.modules] == [True] * 4 + [False] * 2


def test_a_failed_deactivate_goes_through_on_error_and_disables_every_module(rig):
    """
    A module that stops answering: deactivate cannot confirm its disable, on_error follows.

    Every module is disabled (the silent one too: it still acts on what it is sent), the bus
    is closed and the node is unconfigured; configure is refused while the module stays
    silent, and once it answers again configure and activate bring the arm back.
    """
    driver, operator, arm = rig
    activate(operator)
    assert all(m.enabled for m in arm.modules)
    with arm.lock:
        arm.modules[2].silent = True              # joint 3 takes frames, answers none
    assert wait_for(lambda: operator.bus_status().get('hold', '') != '', 10.0)
    assert not operator.transition(Transition.TRANSITION_DEACTIVATE)
    assert wait_for(lambda: operator.lifecycle() == 'unconfigured', 30.0), operator.lifecycle()
    assert driver.driver is None and driver.lifecycle_state == 'unconfigured'
    assert 'deactivate refused' in driver.last_failure, driver.last_failure
    with arm.lock:
        enabled = [m.enabled for m in arm.modules]
    assert enabled == [False] * 6, enabled
    # Still silent: configure is refused with the joint's name, the bus closed again.
    assert not operator.transition(Transition.TRANSITION_CONFIGURE)
    assert operator.lifecycle() == 'unconfigured' and driver.driver is None
    assert 'joint3' in driver.last_failure, driver.last_failure
    with arm.lock:
        arm.modules[2].silent = False
    assert operator.transition(Transition.TRANSITION_CONFIGURE)
    activate(operator)
    assert all(m.enabled for m in arm.modules)


def test_the_jog_intake_alone():
    """Built without a node: checks, refuses by reason, commands only while not blocked."""
    commanded, refusals, blocked = [], [], ['the driver is inactive']
    intake = JogIntake(NAMES, [j.max_speed for j in JOINTS], 'rad_per_s',
                       speed_override=lambda: 0.25, blocked=lambda: blocked[0],
                       command=commanded.append, on_refusal=lambda: refusals.append(1))
    good = conversions.make_joint_jog(['joint2'], [0.1])
    intake.on_jog(good)
    assert commanded == [] and intake.counts.ignored == 1
    assert intake.counts.last_ignored == 'the driver is inactive'
    with pytest.raises(JogRefused) as refused:
        intake.on_jog(conversions.make_joint_jog(['jointX'], [0.1]))
    assert refused.value.reason == 'unknown_joint' and refusals == [1]
    blocked[0] = ''
    intake.on_jog(good)
    assert commanded == [[0.0, 0.1, 0.0, 0.0, 0.0, 0.0]]
    assert intake.counts.received == 3 and intake.counts.refused == 1
