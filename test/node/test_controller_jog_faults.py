"""
Hostile jog commands and a failing tick, with the controller node and real rclpy in one process.

A huge twist publishes no NaN and the tick goes on; a future stamp does not keep the arm moving
and a malformed one is refused with the reason; an exception inside a tick is a fault with the
reason on the status, and a tick that cannot run at all ends the node, in a process with exit
code 1. A test node plays the arm (``test_controller_node.FakeArm``).

The exceptions come from inside the core's real tick, through what it calls: the collision
guard's veto of the jog's next pose (the node gives the core its guard,
``ControllerCore.collision_guard``), or the robot's states check that opens every tick
(``Robot.measured``); the doubles stand in for those, never for the tick itself.
"""

import os
import subprocess
import sys
import time

from control_msgs.msg import JointJog
from geometry_msgs.msg import TwistStamped
from mover6_control.control.robot import Robot
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.controller.node import ControllerNode
from mover6_control.nodes.controller.tick_loop import MAX_TICK_FAILURES
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime import local_dds
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
import ros_testing
from test_controller_node import FakeArm

NS = f'jog_faults_test_{os.getpid()}'
LIMITS = mover6().velocity_limits


class Jogger:
    """Publish twists and joint jogs to the controller from the fake arm's node."""

    def __init__(self, arm):
        self.arm = arm
        self.twist_pub = arm.create_publisher(TwistStamped, 'controller/delta_twist_cmds', 10)
        self.joint_pub = arm.create_publisher(JointJog, 'controller/delta_joint_cmds', 10)

    def now(self):
        return self.arm.get_clock().now().nanoseconds * 1e-9

    def twist(self, linear, angular, ahead=0.0, stamp=None):
        """Send a twist stamped now + ``ahead`` [s] (or with ``stamp``); return its stamp [s]."""
        msg = TwistStamped()
        t = self.now() + ahead
        msg.header.stamp = conversions.seconds_to_stamp(t) if stamp is None else stamp
        msg.header.frame_id = 'base_link'
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = map(float, linear)
        msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = map(float, angular)
        self.twist_pub.publish(msg)
        return t

    def joints(self, names, velocities, ahead=0.0):
        """Send a joint jog stamped now + ``ahead`` [s]; return its stamp [s]."""
        t = self.now() + ahead
        self.joint_pub.publish(conversions.make_joint_jog(names, velocities,
                                                          conversions.seconds_to_stamp(t)))
        return t


@pytest.fixture
def ros(request):
    # conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
    # Inside ./run.sh test's private network namespace: the local configuration (local_dds).
    assert (os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
            or local_dds.requested())
    ns = f'{NS}_{request.node.name.split("[")[0][-20:]}'
    context = rclpy.Context()
    rclpy.init(context=context)
    # tick_priority 0: a real-time tick here would raise every thread of the test process.
    controller = ControllerNode(context=context, namespace=ns, parameter_overrides=[
        Parameter('profile', value='trapezoidal'), Parameter('rate', value=100.0),
        Parameter('tick_priority', value=0)])
    arm = FakeArm(context, namespace=ns, jog_depth=1000)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(controller)
    executor.add_node(arm)

    def spin_until(predicate, timeout=30.0, each=None):
        if ros_testing.spin_until(executor, predicate, timeout, each=each) is None:
            raise AssertionError(f'timed out; last status {arm.status()}')
        return True

    spin_until(lambda: arm.status().get('state') == 'idle')
    yield controller, arm, Jogger(arm), spin_until
    executor.shutdown()
    controller.destroy_node()
    arm.destroy_node()
    rclpy.try_shutdown(context=context)


def stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def stream(spin_until, send, seconds):
    """Call ``send()`` about every 20 ms for ``seconds`` of wall time; return its last value."""
    last = {'value': send(), 'at': time.monotonic()}
    end = time.monotonic() + seconds

    def each():
        if time.monotonic() - last['at'] >= 0.02:
            last['value'], last['at'] = send(), time.monotonic()

    spin_until(lambda: time.monotonic() > end, each=each)
    return last['value']


def test_a_huge_twist_at_home_publishes_no_nan_and_the_tick_goes_on(ros):
    """At home 1e308 killed the tick thread (no JointJog after); away it published NaN."""
    controller, arm, jogger, spin_until = ros
    assert np.allclose(arm.q, 0.0, atol=1e-3)                 # the fake arm starts at home
    first = len(arm.jogs)
    stream(spin_until, lambda: jogger.twist([1e300, 1e308, -1e300], [1e300, 1e307, 1e300]), 1.0)
    spin_until(lambda: arm.status().get('state') == 'idle')
    after = len(arm.jogs)
    spin_until(lambda: len(arm.jogs) > after + 20)            # the ticks go on
    velocities = np.array([m.velocities for m in arm.jogs[first:]])
    assert np.all(np.isfinite(velocities))                   # FakeArm.on_jog raises on NaN too
    assert np.all(np.abs(velocities) <= LIMITS * (1.0 + 1e-6))
    assert np.max(np.abs(velocities)) > 0.1                   # it did jog
    assert controller.ticks.thread.is_alive() and controller.fatal is None
    assert 'jogging' in {conversions.status_values(s)['state'] for s in arm.statuses}
    # (A loaded machine may fault on stale joint states meanwhile: not what is judged here.)
    messages = [s.message for s in arm.statuses]
    assert not any(m.startswith(('tick failed', 'non-finite')) for m in messages), messages


@pytest.mark.parametrize('kind, ahead', [('joints', 1.0), ('twist', 3600.0)])
def test_a_future_stamp_is_refused_and_does_not_keep_the_arm_moving(ros, kind, ahead):
    """A last command stamped now + 1 s moved the arm on for 1.31 s; + 3600 s for good."""
    controller, arm, jogger, spin_until = ros
    arm.q = np.array([0.0, 0.3, 0.6, 0.0, 0.8, 0.0])        # away from home (q5 = 0: singular)
    if kind == 'joints':
        def send(ahead=0.0):
            return jogger.joints(['joint1'], [0.2], ahead)
    else:
        def send(ahead=0.0):
            return jogger.twist([0.0, 0.02, 0.0], [0.0, 0.0, 0.0], ahead)
    stream(spin_until, send, 0.6)
    spin_until(lambda: np.max(np.abs(arm.qd)) > 0.05, each=send)
    last = send()
    send(ahead)
    spin_until(lambda: 'in the future' in arm.status().get('jog_refused', ''))
    spin_until(lambda: arm.status().get('state') == 'idle')

    def zeros():
        return [stamp(m) for m in arm.jogs if stamp(m) > last and not any(m.velocities)]

    spin_until(zeros)
    zero = zeros()[0]
    # By the stamps (the controller's and ours: one clock); 0.1 s timeout + 0.2 s to rest at
    # a_max, well under the 1 s that the future stamp held it before.
    assert zero - last < ahead and zero - last < 1.0, zero - last


def test_a_malformed_stamp_is_refused_with_the_reason_and_changes_nothing(ros):
    controller, arm, jogger, spin_until = ros
    bad = conversions.seconds_to_stamp(jogger.now())
    bad.nanosec = 1_500_000_000
    stream(spin_until, lambda: jogger.twist([0.0, 0.02, 0.0], [0.0, 0.0, 0.0], stamp=bad), 0.3)
    spin_until(lambda: 'malformed stamp' in arm.status().get('jog_refused', ''))
    assert 'nanosec 1500000000' in arm.status()['jog_refused']
    assert arm.status()['state'] == 'idle' and not np.any(arm.qd)


class VetoBreaksOnce:
    """A collision guard whose veto of a jog's next pose raises once, then lets all pass."""

    def __init__(self):
        self.raised = 0

    def __call__(self, plan):
        pass                            # a demand's plan: no collision

    def veto(self, q, q_ahead):
        if not self.raised:
            self.raised += 1
            raise RuntimeError('broken once')
        return None


def always_broken(robot):
    raise RuntimeError('always broken')


def test_an_exception_in_a_tick_is_a_fault_with_the_reason_and_the_tick_goes_on(ros):
    """An exception inside the tick (the guard's veto of the jog) killed the tick thread."""
    controller, arm, jogger, spin_until = ros
    stream(spin_until, lambda: jogger.joints(['joint1'], [0.2]), 0.5)
    guard = VetoBreaksOnce()
    with controller.lock:               # as the node gives the core its guard
        assert controller.core.state == 'jogging'
        controller.core.collision_guard = guard     # the next jogging tick calls its veto
    reason = 'tick failed: RuntimeError: broken once'

    def fault():
        return [s for s in arm.statuses if s.message == reason]

    spin_until(fault)
    values = conversions.status_values(fault()[0])
    assert values['state'] == 'fault' and values['result'] == 'fault'
    assert values['reason'] == reason and conversions.status_level_name(fault()[0]) == 'ERROR'
    faulted = len(arm.jogs)
    spin_until(lambda: arm.status().get('state') == 'idle')   # fresh states clear it
    spin_until(lambda: len(arm.jogs) > faulted + 20)          # and the ticks went on
    assert not any(any(m.velocities) for m in arm.jogs[faulted:])
    assert guard.raised == 1 and controller.fatal is None and controller.ticks.thread.is_alive()


def test_a_tick_that_cannot_run_ends_the_node(ros, monkeypatch):
    """Every tick raising (the robot's states check broken): zero command, the node gives up."""
    controller, arm, jogger, spin_until = ros
    stream(spin_until, lambda: jogger.joints(['joint1'], [0.2]), 0.5)
    with controller.lock:
        monkeypatch.setattr(Robot, 'measured', property(always_broken))
    spin_until(lambda: controller.fatal is not None and not controller.ticks.thread.is_alive())
    # The core's failures, with the last one's reason (not '... failed to publish').
    assert controller.fatal == (f'{MAX_TICK_FAILURES} ticks in a row failed '
                                '(tick failed: RuntimeError: always broken)')
    spin_until(lambda: arm.jogs and not any(arm.jogs[-1].velocities))


BROKEN_CONTROLLER = """
import sys
from mover6_control.control.robot import Robot
from mover6_control.nodes.controller import node as controller_node


def broken(robot):
    raise RuntimeError('always broken')


Robot.measured = property(broken)      # the states check that opens every tick raises
sys.exit(controller_node.main())
"""


def test_a_controller_process_whose_tick_cannot_run_exits_1():
    """The launcher sees it: the process ends by itself with exit code 1 and the reason."""
    proc = subprocess.run(
        [sys.executable, '-c', BROKEN_CONTROLLER, '--ros-args', '-r', f'__ns:=/{NS}_proc'],
        capture_output=True, text=True, timeout=60.0)
    assert proc.returncode == 1, proc.stderr[-2000:]
    fatal = (f'fatal: {MAX_TICK_FAILURES} ticks in a row failed '
             '(tick failed: RuntimeError: always broken)')
    assert fatal in proc.stderr, proc.stderr[-2000:]
