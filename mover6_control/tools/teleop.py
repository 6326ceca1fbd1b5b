"""
Keyboard teleop: jog the arm from a terminal (``./run.sh goal jog``, ``ros2 run ... teleop``).

Publishes geometry_msgs/TwistStamped on /controller/delta_twist_cmds (twist mode) or
control_msgs/JointJog on /controller/delta_joint_cmds (joint mode) at a steady rate while a key
is held, and nothing otherwise: the controller then stops the arm after its command timeout.
A terminal sends a key once, then (after its repeat delay) repeats it; a key counts as held for
``HOLD`` seconds after its last repeat, and ``FIRST_HOLD`` after its first press (so the repeat
delay does not make the motion stutter).

Keys::

    w / s   +x / -x          u / j   roll  + / -  (about x)
    a / d   +y / -y          i / k   pitch + / -  (about y)
    r / f   +z / -z          o / l   yaw   + / -  (about z)
    m       twist mode <-> joint mode    1 .. 6  joint to jog (joint mode: w / s move it)
    t       frame base_link <-> link6 (tool)
    + / -   speed step up / down
    space   stop: one zero command, keys released
    x, q    quit (Ctrl-C too); the terminal is restored on exit in every case

The last line of the terminal shows the mode, frame, speed, what is held and the controller's
state and reason (/controller/status).
"""

from contextlib import contextmanager
import os
import select
import signal
import sys
import termios
import time
import tty
from typing import Callable, Iterator, Optional, TextIO

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from mover6_control.control.servo import FRAMES
from mover6_control.control.status import StatusKey
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime.qos import STATUS_QOS
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

LINEAR_KEYS = {'w': (0, 1.0), 's': (0, -1.0), 'a': (1, 1.0), 'd': (1, -1.0),
               'r': (2, 1.0), 'f': (2, -1.0)}
ANGULAR_KEYS = {'u': (0, 1.0), 'j': (0, -1.0), 'i': (1, 1.0), 'k': (1, -1.0),
                'o': (2, 1.0), 'l': (2, -1.0)}
JOINT_KEYS = {'w': 1.0, 's': -1.0}
QUIT_KEYS = ('x', 'q', '\x03', '\x04')
# Speed steps: fractions of the top speeds below.
SPEED_STEPS = (0.1, 0.25, 0.5, 1.0)
MAX_LINEAR = 0.08       # [m/s]
MAX_ANGULAR = 0.4       # [rad/s]
MAX_JOINT = 0.4         # [rad/s]
HOLD = 0.15             # [s] a key counts as held this long after its last repeat
FIRST_HOLD = 0.6        # [s] ... and this long after its first press (the repeat delay)
RATE = 50.0             # [Hz] publishing rate while a key is held
JOINT_NAMES = tuple(f'joint{i}' for i in range(1, 7))


class Teleop:
    """The key handling, without terminal or ROS: keys and time in, the command to send out."""

    def __init__(self, hold: float = HOLD, first_hold: float = FIRST_HOLD):
        """Start in twist mode, base_link, the second speed step, nothing held."""
        self.hold, self.first_hold = hold, first_hold
        self.mode = 'twist'
        self.frame = FRAMES[0]
        self.speed = 1
        self.joint = 0
        self.held = {}          # key -> time [s] it counts as held until
        self.stop_pending = False

    @property
    def scale(self) -> float:
        """Return the fraction of the top speeds in use."""
        return SPEED_STEPS[self.speed]

    def on_key(self, key: str, now: float) -> bool:
        """Take one key pressed (or repeated) at ``now`` [s]; return False to quit."""
        if key in QUIT_KEYS:
            return False
        if key == ' ':
            self.held.clear()
            self.stop_pending = True
        elif key == 'm':
            self.mode = 'joint' if self.mode == 'twist' else 'twist'
            self.held.clear()
        elif key == 't':
            self.frame = FRAMES[1 - FRAMES.index(self.frame)]
        elif key in ('+', '='):
            self.speed = min(self.speed + 1, len(SPEED_STEPS) - 1)
        elif key in ('-', '_'):
            self.speed = max(self.speed - 1, 0)
        elif key in '123456' and len(key) == 1:
            self.joint = int(key) - 1
            self.held.clear()
        elif self._moves(key):
            repeat = self.held.get(key, -1.0) >= now
            self.held[key] = now + (self.hold if repeat else self.first_hold)
        return True

    def _moves(self, key):
        if self.mode == 'joint':
            return key in JOINT_KEYS
        return key in LINEAR_KEYS or key in ANGULAR_KEYS

    def active(self, now: float) -> list:
        """Return the keys held at ``now`` [s] (forgetting the released ones)."""
        self.held = {k: t for k, t in self.held.items() if t >= now}
        return sorted(self.held)

    def command(self, now: float) -> Optional[tuple]:
        """
        Return what to publish at ``now`` [s], or None (nothing held, nothing to say).

        ``('twist', linear (3,), angular (3,), frame)`` or ``('joint', names, velocities)``;
        after space, one zero twist (or zero joint jog).
        """
        keys = self.active(now)
        if not keys and not self.stop_pending:
            return None
        self.stop_pending = False
        if self.mode == 'joint':
            velocity = sum(JOINT_KEYS[k] for k in keys) * MAX_JOINT * self.scale
            return ('joint', [JOINT_NAMES[self.joint]], [velocity])
        linear, angular = [0.0] * 3, [0.0] * 3
        for key in keys:
            if key in LINEAR_KEYS:
                axis, sign = LINEAR_KEYS[key]
                linear[axis] += sign * MAX_LINEAR * self.scale
            else:
                axis, sign = ANGULAR_KEYS[key]
                angular[axis] += sign * MAX_ANGULAR * self.scale
        return ('twist', linear, angular, self.frame)

    def status_line(self, now: float, controller: str = '') -> str:
        """Return the one-line status: mode, frame, speed, keys held, the controller's word."""
        if self.mode == 'joint':
            where = f'joint mode, {JOINT_NAMES[self.joint]} (w/s)'
            speed = f'{MAX_JOINT * self.scale:.2f} rad/s'
        else:
            where = f'twist in {self.frame}'
            speed = f'{MAX_LINEAR * self.scale:.3f} m/s, {MAX_ANGULAR * self.scale:.2f} rad/s'
        held = ''.join(self.active(now)) or '-'
        line = f'{where} | speed {self.speed + 1}/{len(SPEED_STEPS)} ({speed}) | held {held}'
        return line + (f' | {controller}' if controller else '')


@contextmanager
def raw_terminal(fd: int) -> Iterator[None]:
    """Put the terminal ``fd`` in cbreak mode, no echo; restore it on exit, whatever happens."""
    saved = termios.tcgetattr(fd) if os.isatty(fd) else None
    try:
        if saved is not None:
            tty.setcbreak(fd)
        yield
    finally:
        if saved is not None:
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def read_keys(fd: int, timeout: float) -> str:
    """Return the keys waiting on ``fd`` within ``timeout`` [s] ('' when none)."""
    ready, _, _ = select.select([fd], [], [], max(timeout, 0.0))
    if not ready:
        return ''
    data = os.read(fd, 64)
    if not data:
        raise EOFError('the terminal closed')
    return data.decode(errors='ignore')


def loop(fd: int, teleop: Teleop, publish: Callable[[tuple], None],
         show: Optional[Callable[[str], None]] = None, status: Callable[[], str] = lambda: '',
         rate: float = RATE, clock: Callable[[], float] = time.monotonic,
         spin: Callable[[], None] = lambda: None) -> None:
    """
    Read keys from ``fd`` and ``publish(command)`` at ``rate`` while one is held, until quit.

    ``show(line)`` gets the status line (``status()`` gives the controller's part); ``spin()``
    runs between reads (ROS callbacks). The terminal is restored on return and on any
    exception (``raw_terminal``).
    """
    period = 1.0 / rate
    with raw_terminal(fd):
        deadline = clock()
        while True:
            spin()
            for key in read_keys(fd, deadline - clock()):
                if not teleop.on_key(key, clock()):
                    return 0
            now = clock()
            if now < deadline:
                continue
            deadline = max(deadline + period, now)
            command = teleop.command(now)
            if command is not None:
                publish(command)
            if show is not None:
                show(teleop.status_line(now, status()))


def terminal_show(out: TextIO = sys.stdout) -> Callable[[str], None]:
    """Return a ``show`` that rewrites the last line of ``out`` when the line changes."""
    shown = ['']

    def show(line):
        width = os.get_terminal_size(out.fileno()).columns if out.isatty() else 0
        line = line[:(width or 100) - 1]          # a terminal of unknown size: 100 columns
        if line != shown[0]:
            out.write('\r' + line + '\x1b[K')
            out.flush()
            shown[0] = line
    return show


class TeleopNode(Node):
    """Publish the teleop's commands; keep the controller's latest status for the status line."""

    def __init__(self, **kwargs):
        """Make the two publishers and the status subscription."""
        super().__init__('teleop', **kwargs)
        self.twist_pub = self.create_publisher(TwistStamped, 'controller/delta_twist_cmds', 10)
        self.joint_pub = self.create_publisher(JointJog, 'controller/delta_joint_cmds', 10)
        self.status = None
        self.create_subscription(DiagnosticStatus, 'controller/status', self.on_status,
                                 STATUS_QOS)
        self.executor_ = SingleThreadedExecutor(context=self.context)
        self.executor_.add_node(self)

    def on_status(self, msg: DiagnosticStatus) -> None:
        """Keep the controller's latest status."""
        self.status = msg

    def spin_some(self) -> None:
        """Serve the callbacks that are ready."""
        self.executor_.spin_once(timeout_sec=0.0)

    def publish_command(self, command: tuple) -> None:
        """Publish a ``Teleop.command`` stamped now."""
        stamp = self.get_clock().now().to_msg()
        if command[0] == 'twist':
            _, linear, angular, frame = command
            msg = TwistStamped()
            msg.header.stamp, msg.header.frame_id = stamp, frame
            msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = linear
            msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = angular
            self.twist_pub.publish(msg)
        else:
            _, names, velocities = command
            msg = JointJog()
            msg.header.stamp = stamp
            msg.joint_names, msg.velocities = list(names), [float(v) for v in velocities]
            self.joint_pub.publish(msg)

    def controller_summary(self) -> str:
        """Return the controller's state and message, or that none was heard."""
        if self.status is None:
            return 'controller: not heard yet'
        state = conversions.status_values(self.status).get(StatusKey.STATE, '?')
        message = self.status.message
        return state if message in ('', state) else f'{state}: {message}'

    def destroy_node(self) -> None:
        """Stop the executor, then destroy the node."""
        self.executor_.shutdown()
        super().destroy_node()


def _raise_interrupt(*_):
    raise KeyboardInterrupt


def main(args: Optional[list[str]] = None) -> int:
    """Run the teleop on this terminal until quit; publish to the controller."""
    argv = sys.argv[1:] if args is None else list(args)
    if not sys.stdin.isatty():
        print('teleop needs a terminal (stdin is not one)', file=sys.stderr)
        return 2
    # Our own SIGINT handling: Ctrl-C arrives as a key in cbreak mode, or as KeyboardInterrupt.
    rclpy.init(args=['teleop'] + argv, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, _raise_interrupt)
    signal.signal(signal.SIGINT, _raise_interrupt)
    node = TeleopNode()
    print(__doc__.split('Keys::', 1)[1].split('The last line')[0].rstrip() + '\n')
    code = 0
    try:
        code = loop(sys.stdin.fileno(), Teleop(), node.publish_command, terminal_show(),
                    node.controller_summary, spin=node.spin_some)
    except KeyboardInterrupt:
        code = 0
    finally:
        print()
        node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
