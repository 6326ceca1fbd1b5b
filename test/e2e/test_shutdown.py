"""
Every node exits 0, without a traceback, on the signals a launch system delivers.

Each node runs as its own process in its own session (no terminal, as under ``ros2 launch``) and
gets one SIGINT, two SIGINTs 30 ms apart (a terminal's Ctrl-C to the process group, then the
one launch forwards), or one SIGTERM, sent to its process group. The controller is stopped in
the middle of a motion (a small fake arm here integrates its JointJog into /joint_states) and
its last JointJog, sent after the signal, must be zero: the vendor driver keeps the last command
forever. All nine processes start together so the test takes one start-up, not nine; each
controller's topics are remapped under its own prefix so the three never see each other.
"""

import os
import signal
import threading
import time

from control_msgs.msg import JointJog
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages import conversions, demand_messages
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from ros_testing import NodeProcess, wait_until
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

pytestmark = pytest.mark.e2e

NODES = ('sim_bridge', 'controller', 'planner')
PATTERNS = {'sigint': (signal.SIGINT,),
            'sigint_twice': (signal.SIGINT, signal.SIGINT),
            'sigterm': (signal.SIGTERM,),
            # A process group's SIGTERM, then a launcher's forwarded SIGINT (scripts/launch.sh).
            'sigterm_then_sigint': (signal.SIGTERM, signal.SIGINT)}
SIGNAL_GAP = 0.03          # [s] between two signals of one pattern
READY_LOG = {'sim_bridge': 'mode rad_per_s', 'planner': 'planner ready'}
START_TIMEOUT = 90.0       # [s] nine processes starting at once on a loaded machine
EXIT_TIMEOUT = 20.0        # [s]
TARGET = [0.6, 0.0, 0.0, 0.0, 0.0, 0.0]   # [rad] a demand that takes the controller ~1 s
STATE_PERIOD = 0.01        # [s] the fake arm's /joint_states period


class FakeArm:
    """Integrate one controller's JointJog into /joint_states; remember every JointJog seen."""

    def __init__(self, node, prefix, joint_names):
        self.joint_names = joint_names
        self.q = [0.0] * len(joint_names)
        self.velocities = [0.0] * len(joint_names)
        self.jogs = []                 # (receive time [monotonic s], velocities)
        self.lock = threading.Lock()
        self.states = node.create_publisher(JointState, f'{prefix}/joint_states', 10)
        self.demands = node.create_publisher(Float32MultiArray, f'{prefix}/joint_demands', 10)
        node.create_subscription(JointJog, f'{prefix}/JointJog', self.on_jog, 10)
        self.clock = node.get_clock()

    def on_jog(self, msg):
        """Take the commanded velocities (by name) and remember the message."""
        by_name = dict(zip(msg.joint_names, msg.velocities))
        with self.lock:
            self.velocities = [by_name.get(n, 0.0) for n in self.joint_names]
            self.jogs.append((time.monotonic(), list(self.velocities)))

    def step(self):
        """Move by the last command for one period and publish the state."""
        with self.lock:
            self.q = [q + v * STATE_PERIOD for q, v in zip(self.q, self.velocities)]
            q, qd = list(self.q), list(self.velocities)
        self.states.publish(conversions.make_joint_state(
            self.joint_names, q, qd, stamp=self.clock.now().to_msg()))

    def moving(self):
        """Return True once a non-zero JointJog arrived."""
        with self.lock:
            return any(any(v != 0.0 for v in vel) for _, vel in self.jogs)

    def jogs_after(self, t):
        """Return the velocities of every JointJog received after monotonic time ``t``."""
        with self.lock:
            return [vel for stamp, vel in self.jogs if stamp > t]

    def last_jog(self):
        """Return the velocities of the last JointJog received (None before the first)."""
        with self.lock:
            return self.jogs[-1][1] if self.jogs else None


@pytest.fixture(scope='module')
def world(tmp_path_factory):
    """Start every node for every pattern at once; a test node with a fake arm per controller."""
    log_dir = str(tmp_path_factory.mktemp('shutdown'))
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('shutdown_test', context=context)
    names = mover6().joint_names
    arms, procs = {}, {}
    for pattern in PATTERNS:
        prefix = f'/shutdown_{pattern}'
        arms[pattern] = FakeArm(node, prefix, names)
        for name in NODES:
            # The controller and the planner on the fake arm's topics: their states must not
            # come from the bridges, which the bridge cases end first (a planner slower to start
            # than the four bridges were to end was never ready).
            topics = {'sim_bridge': (), 'planner': ('joint_states',),
                      'controller': ('JointJog', 'joint_states', 'joint_demands')}[name]
            remaps = sum((('-r', f'{topic}:={prefix}/{topic}') for topic in topics), ())
            procs[name, pattern] = NodeProcess(name, log_dir, ros_args=remaps, new_session=True,
                                               log_name=f'{name}_{pattern}')
    node.create_timer(STATE_PERIOD, lambda: [arm.step() for arm in arms.values()])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield procs, arms
    finally:
        for proc in procs.values():
            if proc.alive():
                os.killpg(proc.pid, signal.SIGKILL)
            proc.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(timeout=5.0)


def log_text(proc):
    """Return everything the process wrote so far."""
    with open(proc.log_path) as f:
        return f.read()


def wait_ready(name, proc, arm):
    """Wait until the node is up (its log line; for the controller: it is driving the arm)."""
    if name != 'controller':
        return wait_until(lambda: not proc.alive() or READY_LOG[name] in log_text(proc),
                          START_TIMEOUT) and proc.alive()
    if not wait_until(lambda: not proc.alive() or arm.jogs_after(0.0), START_TIMEOUT):
        return False
    last_demand = [0.0]

    def moving():
        if arm.moving():
            return True
        if time.monotonic() - last_demand[0] > 0.5:      # the first may come before a state
            arm.demands.publish(demand_messages.make_demands([TARGET]))
            last_demand[0] = time.monotonic()
        return False
    return wait_until(moving, 30.0) and proc.alive()


@pytest.mark.parametrize('pattern', PATTERNS)
@pytest.mark.parametrize('name', NODES)
def test_node_exits_cleanly_on_signals(world, name, pattern):
    """The node exits 0 with no traceback; the controller's last JointJog is zero."""
    procs, arms = world
    proc, arm = procs[name, pattern], arms[pattern]
    assert wait_ready(name, proc, arm), f'{name} did not come up:\n{log_text(proc)}'
    signalled = time.monotonic()
    moving_when_signalled = name == 'controller' and any(arm.last_jog())
    for i, signum in enumerate(PATTERNS[pattern]):
        if i:
            time.sleep(SIGNAL_GAP)       # the pattern itself, not a wait for a condition
        os.killpg(proc.pid, signum)
    assert wait_until(lambda: not proc.alive(), EXIT_TIMEOUT), \
        f'{name} still running {EXIT_TIMEOUT} s after {pattern}:\n{log_text(proc)}'
    output = log_text(proc)
    assert proc.proc.returncode == 0, f'{name} exit code {proc.proc.returncode}:\n{output}'
    assert 'Traceback' not in output, output
    if name == 'controller':
        assert moving_when_signalled, 'the motion ended before the signal: no test of the zero'
        zero = [0.0] * len(TARGET)
        # The last command may still be in flight when the process is gone.
        assert wait_until(lambda: arm.jogs_after(signalled)
                          and arm.jogs_after(signalled)[-1] == zero, 5.0), \
            f'last JointJog after {pattern}: {arm.jogs_after(signalled)[-3:]}\n{output}'
