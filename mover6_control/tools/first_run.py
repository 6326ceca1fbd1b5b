"""
The first-run check of a Mover6: each joint jogged +5 deg and back, its direction confirmed.

``ros2 run mover6_control first_run`` (or ``./run.sh first-run``), with the driver running and
the arm enabled (``~/reset``, ``~/enable``; no controller: this tool sends /JointJog itself).
For each joint in turn it jogs ``--angle`` (5 deg) at ``--speed`` (10 % of the joint's maximum
speed) in the joint's positive direction and back, closed-loop on /joint_states, and reports
the encoder ticks (by the joint file's scaling, the counts the module reported) and the angle
moved. The operator confirms, for each joint, that it turned in its positive direction as
docs/real_arm.md pictures it (docs/images/joint_N.png) and, if they measured it, that the angle
was about right. It ends with a summary and writes the calibration file
(``hardware.calibration``), which the driver reads (parameter ``calibration_file``): a direction
seen wrong refuses the driver's start until the gear's sign is fixed and the check run again.

``--yes`` answers yes to every question (the simulated arm, where the check cannot fail: it
counts with the same joint file). ``--can-sim`` starts the simulated arm (``can_sim``) and the
driver (enabled at start) for the check and stops them after it. A joint too near its upper
limit to move ``--angle`` is skipped with the reason; a joint that does not move in time stops
the check (is the arm enabled?).

The parts: ``JointMove`` (the figures of one joint's move), ``Operator`` (the questions),
``ArmLink`` (the ROS node: /joint_states in, /JointJog out), ``SimulatedRig`` (can_sim and the
driver as processes, for ``--can-sim``) and ``FirstRun`` (the check, joint by joint).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import datetime
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Callable, Optional, Sequence

from control_msgs.msg import JointJog
from mover6_control.hardware.calibration import JointCalibration, write_calibration
from mover6_control.hardware.scaling import JOINTS_YAML, JointScale, load_joints
from mover6_control.nodes.messages import conversions
from mover6_control.resources import executable_command
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState

JOG_PERIOD = 0.02
"""[s] between two JointJogs (the driver's command_timeout is 0.2 s)."""
SETTLE = 0.3
"""[s] of /joint_states at rest (no joint faster than ``AT_REST_BELOW``) before a reading."""
AT_REST_BELOW = 1e-3
"""[rad/s]"""
TOLERANCE = math.radians(0.05)
"""[rad] a jog is done this near its target (or within a tick, for the coarse wrist encoders)."""
APPROACH = 2.0
"""[1/s] the jog's speed near its target: this times the distance left (slows down on the way)."""
STATES_FRESH = 0.15
"""[s] a position older than this is not jogged on (the driver publishes every 0.05 s)."""


@dataclass(frozen=True)
class JointMove:
    """One joint's move: from ``q0`` to ``q1`` and back to ``q2`` [rad]."""

    scale: JointScale
    q0: float
    q1: float
    q2: float

    @property
    def angle_deg(self) -> float:
        """Return the angle moved out [deg]."""
        return math.degrees(self.q1 - self.q0)

    @property
    def ticks(self) -> int:
        """Return the encoder ticks moved out (the joint file's scaling) [ticks]."""
        return self.scale.to_ticks(self.q1) - self.scale.to_ticks(self.q0)

    @property
    def back_error_deg(self) -> float:
        """Return how far from the start the joint came back [deg]."""
        return math.degrees(self.q2 - self.q0)


class Operator:
    """Ask the operator yes/no questions on ``ask`` (``input``), or answer yes (``--yes``)."""

    def __init__(self, yes: bool, ask: Callable[[str], str] = input,
                 say: Callable[[str], None] = print) -> None:
        """Answer yes to everything with ``yes``; else ask with ``ask``, print with ``say``."""
        self.yes, self.ask, self.say = yes, ask, say

    def confirm(self, question: str) -> Optional[bool]:
        """Return True (y), False (n) or None (s: skip, not known) for ``question``."""
        if self.yes:
            self.say(f'{question} [y/n/s] y (--yes)')
            return True
        while True:
            answer = self.ask(f'{question} [y/n/s] ').strip().lower()
            if answer in ('y', 'yes', 'n', 'no', 's', 'skip'):
                return {'y': True, 'n': False, 's': None}[answer[0]]


class ArmLink(Node):
    """/joint_states in, /JointJog (rad_per_s) out: one joint jogged to an angle, or stopped."""

    def __init__(self, names: Sequence[str]) -> None:
        """Subscribe /joint_states; publish /JointJog for ``names``."""
        super().__init__('first_run')
        self.names = list(names)
        self.q = None             # the latest positions (in ``names`` order) [rad]
        self.qd = None
        self.stamp = 0.0          # when they came (monotonic) [s]
        self.pub = self.create_publisher(JointJog, 'JointJog', 10)
        self.create_subscription(JointState, 'joint_states', self.on_states, 10)
        self.executor_ = SingleThreadedExecutor(context=self.context)
        self.executor_.add_node(self)

    def on_states(self, msg: JointState) -> None:
        """Keep the latest positions and velocities of the arm's joints."""
        index = {n: i for i, n in enumerate(msg.name)}
        if all(n in index for n in self.names):
            self.q = [msg.position[index[n]] for n in self.names]
            self.qd = [msg.velocity[index[n]] if len(msg.velocity) == len(msg.name) else 0.0
                       for n in self.names]
            self.stamp = time.monotonic()

    def spin_for(self, seconds: float) -> None:
        """Spin until ``seconds`` passed."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor_.spin_once(timeout_sec=max(0.0, min(JOG_PERIOD, end -
                                                              time.monotonic())))

    def jog(self, velocities: Sequence[float]) -> None:
        """Publish one JointJog [rad/s] for every joint."""
        self.pub.publish(conversions.make_joint_jog(self.names, list(velocities)))

    def wait_states(self, timeout: float) -> bool:
        """Wait up to ``timeout`` [s] for /joint_states; return whether they came."""
        end = time.monotonic() + timeout
        while self.q is None and time.monotonic() < end:
            self.executor_.spin_once(timeout_sec=0.1)
        return self.q is not None

    def at_rest(self, timeout: float) -> Optional[list[float]]:
        """Return the positions once the arm rested ``SETTLE`` [s] (None after ``timeout``)."""
        end = time.monotonic() + timeout
        still_since = None
        while time.monotonic() < end:
            self.jog([0.0] * len(self.names))
            self.spin_for(JOG_PERIOD)
            moving = self.qd is None or any(abs(v) > AT_REST_BELOW for v in self.qd) or \
                time.monotonic() - self.stamp > 0.5
            still_since = None if moving else (still_since or time.monotonic())
            if still_since is not None and time.monotonic() - still_since >= SETTLE:
                return list(self.q)
        return None

    def move(self, i: int, target: float, speed: float, tolerance: float,
             timeout: float) -> bool:
        """
        Jog joint ``i`` towards ``target`` [rad], at most at ``speed`` [rad/s]; then stop.

        It slows down on the way in (``APPROACH`` [1/s] times the distance, at least a tenth of
        ``speed``), so the set-point, which runs ahead of the joint, does not carry it past;
        done within ``tolerance`` [rad] (about a tick).
        """
        end = time.monotonic() + timeout
        velocities = [0.0] * len(self.names)
        while time.monotonic() < end:
            if time.monotonic() - self.stamp > STATES_FRESH:
                # No fresh position (a loaded machine): hold rather than jog on an old one,
                # which carries the joint past the target and back (hunting).
                self.jog([0.0] * len(self.names))
                self.spin_for(JOG_PERIOD)
                continue
            error = target - self.q[i]
            if abs(error) <= tolerance:
                self.jog([0.0] * len(self.names))
                return True
            velocities[i] = math.copysign(max(min(speed, APPROACH * abs(error)), speed / 10),
                                          error)
            self.jog(velocities)
            self.spin_for(JOG_PERIOD)
        self.jog([0.0] * len(self.names))
        return False


class SimulatedRig:
    """``can_sim`` and the driver (enabled at start) as processes, for ``--can-sim``."""

    def __init__(self, joints_file: str) -> None:
        """Start can_sim on a pty in a fresh folder, then the driver on it."""
        self.folder = tempfile.mkdtemp(prefix='mover6_first_run_')
        self.link = os.path.join(self.folder, 'mover6-can')
        self.log = open(os.path.join(self.folder, 'rig.log'), 'w')
        self.processes = []
        self._start(executable_command('can_sim') +
                    ['--link', self.link, '--joints-file', joints_file])
        end = time.monotonic() + 30.0
        while not os.path.exists(self.link) and time.monotonic() < end:
            if self.processes[0].poll() is not None:
                break
            time.sleep(0.05)
        if not os.path.exists(self.link):
            self.close()
            raise RuntimeError(f'can_sim did not come up (see {self.log.name})')
        self._start(executable_command('driver') + [
            '--ros-args', '-p', 'can_interface:=cpr_usb2can', '-p', f'can_channel:={self.link}',
            '-p', 'enable_on_start:=true', '-p', f'joints_file:={joints_file}'])

    def _start(self, command: list[str]) -> None:
        self.processes.append(subprocess.Popen(command, stdout=self.log,
                                               stderr=subprocess.STDOUT,
                                               start_new_session=True))

    def close(self) -> None:
        """Stop the driver, then can_sim (SIGINT, then SIGKILL after 10 s)."""
        for proc in reversed(self.processes):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(10.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(5.0)
        self.log.close()


class FirstRun:
    """The check, joint by joint (module docstring); ``results`` by joint name."""

    def __init__(self, link: ArmLink, joints: Sequence[JointScale], operator: Operator,
                 angle: float, speed: float, say: Callable[[str], None] = print) -> None:
        """Check ``joints`` through ``link``: ``angle`` [rad] out and back at ``speed`` (0..1)."""
        self.link, self.joints, self.operator = link, joints, operator
        self.angle, self.speed, self.say = angle, speed, say
        self.results: dict[str, JointCalibration] = {}
        self.moves: dict[str, JointMove] = {}

    def run(self, which: Sequence[int]) -> bool:
        """Check the joints ``which`` (1-based) in turn; return False if the arm did not move."""
        for n in which:
            if not self.check(n - 1):
                return False
        return True

    def check(self, i: int) -> bool:
        """Check joint ``i`` (0-based); return False if it did not move in time."""
        scale = self.joints[i]
        speed = self.speed * scale.max_speed
        timeout = 3.0 * self.angle / speed + 10.0
        q = self.link.at_rest(10.0)
        if q is None:
            self.say(f'{scale.name}: the arm does not come to rest: stopped')
            return False
        if q[i] + self.angle > scale.limits_rad()[1]:
            self.say(f'{scale.name}: skipped, {math.degrees(q[i]):.1f} deg is within '
                     f'{math.degrees(self.angle):.1f} deg of its upper limit: move it away')
            self.results[scale.name] = JointCalibration(scale.gear, None, None, None, None)
            return True
        self.say(f'{scale.name}: jogging +{math.degrees(self.angle):.1f} deg at '
                 f'{self.speed:.0%} of its maximum speed, then back')
        q0 = q[i]
        tolerance = max(0.6 * scale.tick, TOLERANCE)
        if not self.link.move(i, q0 + self.angle, speed, tolerance, timeout):
            self.say(f'{scale.name}: did not reach +{math.degrees(self.angle):.1f} deg within '
                     f'{timeout:.0f} s: is the arm enabled? Stopped')
            return False
        q1 = self.link.at_rest(10.0)[i]
        if not self.link.move(i, q0, speed, tolerance, timeout):
            self.say(f'{scale.name}: did not come back within {timeout:.0f} s: stopped')
            return False
        q2 = self.link.at_rest(10.0)[i]
        move = JointMove(scale, q0, q1, q2)
        self.moves[scale.name] = move
        self.say(f'{scale.name}: moved {move.angle_deg:+.2f} deg = {move.ticks:+d} encoder '
                 f'ticks (gear {scale.gear:g}, {scale.ticks_per_rev} ticks per motor turn), '
                 f'back within {move.back_error_deg:+.2f} deg')
        number = i + 1
        sign = self.operator.confirm(
            f'{scale.name}: did it turn in its positive direction as docs/real_arm.md shows '
            f'(docs/images/joint{number}.png) and back?')
        size = self.operator.confirm(
            f'{scale.name}: if you measured it, was the angle about '
            f'{move.angle_deg:.1f} deg? (s: not measured)')
        self.results[scale.name] = JointCalibration(
            scale.gear, sign, size, move.ticks, round(move.angle_deg, 3))
        return True

    def summary(self) -> list[str]:
        """Return the summary lines: per joint, what was confirmed."""
        words = {True: 'confirmed', False: 'WRONG', None: 'not checked'}
        lines = []
        for j in self.joints:
            c = self.results.get(j.name)
            if c is None:
                lines.append(f'{j.name}: not run')
                continue
            moved = '' if c.angle_moved_deg is None else \
                f', moved {c.angle_moved_deg:+.2f} deg = {c.ticks_moved:+d} ticks'
            lines.append(f'{j.name}: direction {words[c.sign_confirmed]}, angle '
                         f'{words[c.scale_confirmed]}{moved}')
        return lines


def parse_args(argv: Optional[list[str]]) -> argparse.Namespace:
    """Return the command line's options."""
    parser = argparse.ArgumentParser(
        prog='first_run', description='Jog each joint +5 deg and back, confirm its direction, '
        'write the calibration file the driver reads (see docs/real_arm.md).')
    parser.add_argument('--yes', action='store_true',
                        help='answer yes to every question (the simulated arm)')
    parser.add_argument('--can-sim', action='store_true',
                        help='start can_sim and the driver (enabled) for the check')
    parser.add_argument('--joints', type=int, nargs='+', default=[1, 2, 3, 4, 5, 6],
                        choices=range(1, 7), metavar='N', help='joints to check (default all)')
    parser.add_argument('--angle', type=float, default=5.0, help='[deg] (default 5)')
    parser.add_argument('--speed', type=float, default=0.1,
                        help="fraction of each joint's maximum speed (default 0.1)")
    parser.add_argument('--joints-file', default=JOINTS_YAML,
                        help="the joint file the driver drives with (default: the package's)")
    parser.add_argument('--output', default='mover6_calibration.yaml',
                        help='the calibration file to write (default: %(default)s)')
    args, _ = parser.parse_known_args(argv)      # --ros-args ... go to rclpy
    if not 0.0 < args.angle <= 20.0 or not 0.0 < args.speed <= 0.5:
        parser.error('--angle must be in (0, 20] deg and --speed in (0, 0.5]')
    return args


def main(argv: Optional[list[str]] = None) -> int:
    """Run the check; return 0 when every joint checked was confirmed, 1 otherwise."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    _, joints = load_joints(args.joints_file)
    rig = SimulatedRig(args.joints_file) if args.can_sim else None
    rclpy.init(args=['first_run'] + argv)
    link = ArmLink([j.name for j in joints])
    check = FirstRun(link, joints, Operator(args.yes), math.radians(args.angle), args.speed)
    done = threading.Event()
    try:
        if not link.wait_states(60.0):
            print('first_run: no /joint_states within 60 s: is the driver running?')
            return 1
        print(f'first_run: {len(args.joints)} joints, +{args.angle:g} deg and back at '
              f'{args.speed:.0%} speed')
        ok = check.run(args.joints)
        done.set()
    except KeyboardInterrupt:
        ok = False
    finally:
        if link.q is not None:
            link.jog([0.0] * len(joints))
        link.destroy_node()
        rclpy.try_shutdown()
        if rig is not None:
            rig.close()
    print('first_run summary:')
    for line in check.summary():
        print(f'  {line}')
    if check.results:
        stamp = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ')
        write_calibration(args.output, check.results, stamp, os.path.abspath(args.joints_file))
        print(f'first_run: wrote {args.output}; give it to the driver: '
              f'-p calibration_file:={os.path.abspath(args.output)}')
    confirmed = all(c.sign_confirmed for c in check.results.values()) and \
        len(check.results) == len(args.joints)
    return 0 if ok and done.is_set() and confirmed else 1


if __name__ == '__main__':
    sys.exit(main())
