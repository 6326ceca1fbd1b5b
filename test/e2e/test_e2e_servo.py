"""
End to end jogging: the MuJoCo bridge and the controller as processes, twists sent from here.

What is judged is what flowed: /joint_states from the bridge (the flange pose by FK), /JointJog
from the controller and /controller/status. From a pose away from home (the bridge starts there)
a +0.02 m/s twist along x for 2 s moves the flange 35-45 mm along x, on the line and with its
orientation kept, and the arm is at rest within 0.3 s of the last command; the same in the tool
frame; stale commands stop it; towards the wrist singularity it slows and halts before it with
the reason on the status, and away from it it moves.

The bridge and the controller run with their shipped timing (real time, the system clock), as
the launchers start them; the bridge starts at ``Q_AWAY`` (its ``initial_q``, as a user sets it
with ``MOVER6_SIM_ARGS``). The twists' stamps, every duration here and the 0.3 s to rest are of
the system clock; a gap in the twists over the 0.1 s command timeout (rightly) makes the
controller decelerate.
"""

import time

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, jacobian
from mover6_control.kinematics.rotations import rotation_angle_between
from mover6_control.nodes.messages import conversions
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from ros_testing import Stack, wait_until
from sensor_msgs.msg import JointState

pytestmark = pytest.mark.e2e

ARM = mover6()
Q_AWAY = [0.0, 0.3, 0.6, 0.0, 0.8, 0.0]
RATE = 100.0            # [Hz] twists sent while jogging
REST_SPEED = 0.002      # [rad/s] every joint slower than this: at rest


class Jogger(Node):
    """Send twists; record /joint_states, /JointJog and /controller/status (the node's clock)."""

    def __init__(self):
        super().__init__('e2e_jogger')
        self.twist_pub = self.create_publisher(TwistStamped, 'controller/delta_twist_cmds', 10)
        self.reset_pub = self.create_publisher(JointState, 'sim_bridge/reset_to', 10)
        self.states = []        # (t, q, qd)
        self.jogs = []          # (t, velocities)
        self.statuses = []      # (t, DiagnosticStatus)
        self.sent = []          # time of each twist sent
        self.create_subscription(JointState, 'joint_states', self.on_states, 10)
        self.create_subscription(JointJog, 'JointJog', self.on_jog, 50)
        qos = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(DiagnosticStatus, 'controller/status', self.on_status, qos)
        self.executor_ = SingleThreadedExecutor()
        self.executor_.add_node(self)

    def now(self):
        """Return the node's time [s] (the system clock's, as the stack's)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def on_states(self, msg):
        q, qd = conversions.joint_state_from_msg(msg, list(ARM.joint_names))
        self.states.append((conversions.stamp_to_seconds(msg.header.stamp), q, qd))

    def on_jog(self, msg):
        self.jogs.append((conversions.stamp_to_seconds(msg.header.stamp),
                          np.array(msg.velocities)))

    def on_status(self, msg):
        self.statuses.append((self.now(), msg))

    def spin(self, seconds):
        """Serve callbacks for ``seconds`` of wall time."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor_.spin_once(timeout_sec=min(0.005, max(end - time.monotonic(), 0.0)))

    def spin_for(self, seconds):
        """Serve callbacks for ``seconds`` of the node's clock (at most 30x in wall time)."""
        end, wall_end = self.now() + seconds, time.monotonic() + 30.0 * seconds
        while self.now() < end and time.monotonic() < wall_end:
            self.spin(0.005)

    @property
    def q(self):
        return self.states[-1][1]

    def status(self):
        return conversions.status_values(self.statuses[-1][1]) if self.statuses else {}

    def send(self, linear, angular, frame='base_link', age=0.0):
        msg = TwistStamped()
        stamp = self.now() - age
        self.sent.append(self.now())
        msg.header.stamp = conversions.seconds_to_stamp(stamp)
        msg.header.frame_id = frame
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = (float(v) for v in linear)
        msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = (float(v)
                                                                         for v in angular)
        self.twist_pub.publish(msg)

    def stream(self, seconds, linear, angular, frame='base_link', age=0.0, until=None):
        """
        Send the twist every ``1 / RATE`` for ``seconds`` (or until ``until()``).

        Return the time of the last one sent.
        """
        end = self.now() + seconds
        wall_end = time.monotonic() + 30.0 * seconds
        last = self.now()
        while self.now() < end and time.monotonic() < wall_end and not (until and until()):
            self.send(linear, angular, frame, age)
            last = self.now()
            self.spin_for(1.0 / RATE)
        return last

    def at_rest_since(self, t):
        """Return when the arm was last seen moving after ``t`` (t when it never was)."""
        moving = [s for s, _, qd in self.states if s >= t and np.max(np.abs(qd)) > REST_SPEED]
        return moving[-1] if moving else t

    def timeline(self, since):
        """Return the statuses and the JointJog gaps since ``since``, for a failure message."""
        lines = [f'{t - since:7.3f} s {conversions.status_values(s).get("state")}: {s.message}'
                 for t, s in self.statuses if t >= since]
        times = [t for t, _ in self.jogs if t >= since]
        gap = max(np.diff(times)) if len(times) > 1 else float('nan')
        moving = [t - since for t, v in self.jogs if t >= since and np.any(v)]
        sent = [t for t in self.sent if t >= since]
        sent_gap = max(np.diff(sent)) if len(sent) > 1 else float('nan')
        lines.append(f'{len(times)} JointJog, longest gap {gap:.3f} s, non-zero from '
                     f'{moving[:1]} to {moving[-1:]} s; {len(sent)} twists sent, longest gap '
                     f'{sent_gap:.3f} s')
        return '\n'.join(lines)

    def reset_to(self, q):
        """Put the simulated arm at ``q`` once the controller is idle (no jog still running)."""
        assert wait_until(lambda: self.status().get('state') == 'idle', 5.0, self.spin), \
            self.status()
        self.reset_pub.publish(JointState(name=list(ARM.joint_names), position=list(q)))
        assert wait_until(lambda: np.allclose(self.q, q, atol=1e-3), 5.0, self.spin), self.q
        self.spin_for(0.3)


@pytest.fixture(scope='module')
def jogger(tmp_path_factory):
    """Start the bridge (at Q_AWAY) and the controller as processes; yield a jogger here."""
    initial = '[' + ', '.join(f'{v:.1f}' for v in Q_AWAY) + ']'
    with Stack(tmp_path_factory.mktemp('e2e_servo_logs'), sim={'initial_q': initial},
               names=('sim_bridge', 'controller')) as stack:
        rclpy.init()
        node = Jogger()
        try:
            ready = wait_until(lambda: node.states and node.now() > 0.0
                               and node.status().get('state') == 'idle', 30.0, node.spin)
            assert ready, stack.report()
            node.stack = stack
            yield node
        finally:
            node.executor_.shutdown()
            node.destroy_node()
            rclpy.try_shutdown()


def jog_line(node, frame):
    """Jog +0.02 m/s along x of ``frame`` for 2 s from Q_AWAY; return the figures."""
    node.reset_to(Q_AWAY)
    node.since = node.now()
    T0 = fk(ARM, node.q)
    x = np.array([1.0, 0.0, 0.0]) if frame == 'base_link' else T0[:3, 0]
    last = node.stream(2.0, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], frame)
    node.spin_for(1.0)
    T1 = fk(ARM, node.q)
    d = T1[:3, 3] - T0[:3, 3]
    along = float(d @ x)
    off = float(np.linalg.norm(d - along * x))
    # Off the line all along the way, not only at the end.
    worst = max(np.linalg.norm((fk(ARM, q)[:3, 3] - T0[:3, 3])
                               - ((fk(ARM, q)[:3, 3] - T0[:3, 3]) @ x) * x)
                for t, q, _ in node.states if t >= last - 2.0)
    rotation = rotation_angle_between(T0[:3, :3], T1[:3, :3])
    return along, max(off, worst), rotation, node.at_rest_since(last) - last


@pytest.mark.parametrize('frame', ['base_link', 'link6'])
def test_a_twist_moves_the_flange_along_its_line_and_stops(jogger, frame):
    """40 mm along x (base or tool), < 2 mm off the line, < 0.01 rad, at rest within 0.3 s."""
    along, off, rotation, rest = jog_line(jogger, frame)
    report = f'along {along:.4f} m, off {off:.5f} m, rotation {rotation:.5f} rad, ' \
             f'rest after {rest:.3f} s\n{jogger.timeline(jogger.since)}\n' \
             f'{jogger.stack.report()}'
    assert 0.035 <= along <= 0.045, report
    assert off < 0.002 and rotation < 0.01, report
    assert rest < 0.3, report
    values = jogger.status()
    assert values['state'] == 'idle' and values['result'] == 'jog_stopped', values
    assert 'stale' in values['reason'], values


def test_stale_commands_stop_the_arm(jogger):
    """Commands older than the timeout start nothing, and stop a jog that runs."""
    jogger.reset_to(Q_AWAY)
    q0 = jogger.q.copy()
    jogger.stream(0.5, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], age=0.5)
    assert np.max(np.abs(jogger.q - q0)) < 1e-3
    assert 'older than the timeout' in jogger.status().get('jog_refused', ''), jogger.status()
    jogger.stream(0.5, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0])          # fresh: jogging
    assert jogger.status()['state'] == 'jogging'
    switched = jogger.now()
    jogger.stream(1.0, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], age=0.5)  # stale from now on
    assert jogger.at_rest_since(switched) - switched < 0.3
    values = jogger.status()
    assert values['state'] == 'idle' and 'stale' in values['reason'], values


def test_towards_the_wrist_singularity_slows_and_halts_away_moves(jogger):
    """Turning q5 towards 0: slowed, then halted before it with the reason; back: it moves."""
    jogger.reset_to(Q_AWAY)
    column = jacobian(ARM, jogger.q)[:, 4] * 0.3          # joint 5 alone at 0.3 rad/s
    start = jogger.now()

    def halted():
        return 'halted before a singularity' in jogger.status().get('jog_reason', '')

    jogger.stream(8.0, -column[:3], -column[3:], until=halted)
    assert halted(), f'{jogger.status()}\n{jogger.stack.report()}'
    halt_seen = jogger.now()
    jogger.stream(0.5, -column[:3], -column[3:])           # still asking: stays halted
    assert halted() and jogger.at_rest_since(halt_seen) - halt_seen < 0.3
    q_halt = jogger.q.copy()
    assert q_halt[4] > 0.1, q_halt                          # stopped before q5 = 0
    reasons = [conversions.status_values(s)['jog_reason'] for t, s in jogger.statuses
               if t >= start and 'jog_reason' in conversions.status_values(s)]
    assert any(r.startswith('slowed') for r in reasons), reasons
    status = jogger.statuses[-1][1]
    assert conversions.status_level_name(status) == 'WARN'
    assert 'halted before a singularity' in status.message
    speeds = [abs(qd[4]) for t, _, qd in jogger.states if start <= t <= halt_seen]
    assert max(speeds[-20:]) < 0.5 * max(speeds), 'slowed before halting'
    jogger.stream(1.0, column[:3], column[3:])              # away from it
    assert jogger.q[4] > q_halt[4] + 0.1, (q_halt, jogger.q)


def test_bad_commands_are_refused_with_the_reason(jogger):
    """An unknown frame or a non-finite twist moves nothing; the status says why."""
    jogger.reset_to(Q_AWAY)
    q0 = jogger.q.copy()
    jogger.stream(0.3, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], frame='world')
    assert 'frame' in jogger.status().get('jog_refused', ''), jogger.status()
    jogger.stream(0.3, [float('nan'), 0.0, 0.0], [0.0, 0.0, 0.0])
    assert 'non-finite' in jogger.status().get('jog_refused', ''), jogger.status()
    assert np.max(np.abs(jogger.q - q0)) < 1e-3
    assert jogger.status()['state'] == 'idle'
