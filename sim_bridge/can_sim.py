"""
The CAN-level Mover6 (``sim_bridge.can_arm``) on a wire: a python-can bus or a serial pty.

``ros2 run mover6_control can_sim --link /tmp/mover6-can`` opens a pseudo-terminal that speaks
the CPR USB2CAN adapter's serial framing (11-byte frames, ``mover6_control.hardware.usb2can``),
links its device to ``--link`` and answers there as the arm's six motor modules: a driver opens
that path exactly as it opens ``/dev/ttyUSB0`` on the real arm. It runs until SIGINT or
SIGTERM, then removes the link and the control socket. No ROS here. It runs at SCHED_FIFO
``--priority`` (60) where the system allows it: the modules it stands for never wait for a CPU,
and on a loaded machine a simulator at normal priority missed the driver's set-points for longer
than the driver's silence limit (then three cycles), which latched a fault that held the arm for
the rest of the run.

Control channel, for tests and for trying faults by hand: a unix stream socket (``--control``,
default the link's path plus ``.control``) taking one command per line and answering each with
one line of JSON, ``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``:

    status                       the arm: time, q [rad], encoders, each module, wire counters
    flags JOINT FLAGS [sticky]   raise error flags (e.g. 0x10) on a module; sticky: a reset
                                 does not clear them
    silent JOINT on|off          the module stops answering, or answers again
    corrupt COUNT [JOINT]        flip a byte in each of the next COUNT frames sent (of JOINT's
                                 module only, if given): the adapter's reader must drop them
    inputs BITS                  set the arm's digital inputs (joint 1's module, 0..0x7F)
    frames                       every frame each module took since the last ``frames``, and
                                 forgets them: ``modules`` [{frames: [[time, kind, ticks]],
                                 lost}] (time on this process's monotonic clock [s], ``now``
                                 beside it; kind setpoint, reset, enable, disable, reference,
                                 set_zero; ticks the set-point on the wire, else null; at most
                                 4096 a module, ``lost`` the older ones): the set-point steps
                                 and the disables a driver sent, as the modules saw them
    unplug                       the adapter pulled: the pty is closed (a driver's reads and
                                 writes fail) and the link removed; the modules keep running
                                 (their watchdog stops them)
    replug                       the adapter back: a new pty, linked at the same path

(``control()`` below sends one; e.g. ``python3 -m sim_bridge.can_sim --send PATH status``.)

In-process, ``BusServer`` answers on any python-can bus (the unit tests use the ``virtual``
interface).
"""

from __future__ import annotations

import argparse
import json
import os
import select
import signal
import socket
import sys
import threading
import time
import tty
from typing import Optional, Sequence

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol, usb2can
from mover6_control.hardware.scaling import JOINTS_YAML, load_joints
from mover6_control.kinematics.arm import LIMIT_SETS, mover6
from mover6_control.realtime import run_at_priority
import numpy as np
from sim_bridge.can_arm import CanArm, ModuleTiming

COMMAND_IDS = tuple(protocol.command_id(j) for j in protocol.JOINTS)
SIM_PRIORITY = 60
"""can_sim's SCHED_FIFO priority by default: the modules it stands for are hardware."""


def build_arm(limit_set: str = 'hardware', joints_file: str = JOINTS_YAML,
              home_q: Optional[Sequence[float]] = None,
              timing: ModuleTiming | None = None, answers_commands: bool = True) -> CanArm:
    """
    Return the CAN-level Mover6 counting with the joint file the driver reads.

    ``answers_commands``: the modules answer commands as well as set-points (``can_arm``).
    """
    _, joints = load_joints(joints_file)
    return CanArm(mover6(limit_set), joints, timing,
                  None if home_q is None else np.asarray(home_q, dtype=float),
                  answers_commands=answers_commands)


class BusServer:
    """Answer as the arm on a python-can ``bus``; ``poll`` once per loop pass."""

    def __init__(self, arm: CanArm, bus: can.BusABC, clock=time.monotonic) -> None:
        """Serve ``arm`` on ``bus``; ``clock`` gives the time [s]."""
        self.arm, self.bus, self.clock = arm, bus, clock

    def poll(self, timeout: float) -> None:
        """
        Take what arrives within ``timeout`` [s], answer it, run the arm to now.

        The time the watchdog looks at is read before the bus is drained (as ``SerialArm``
        does): every frame sent before it is taken first, so a server held up between its last
        read and its clock (another thread, the interpreter lock) trips no watchdog of a driver
        that sent in time. Each frame read after the first is stamped with the clock read when
        it is taken: a drain that took long (the physics catching up on a held-up server) would
        otherwise stamp the frames that came meanwhile with the time before it, and the
        watchdog would find them half a second old at the next pass.
        """
        msg = self.bus.recv(timeout)
        now = self.clock()
        while msg is not None:
            if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
                for can_id, data in self.arm.receive(msg.arbitration_id,
                                                     bytes(msg.data[:msg.dlc]), now):
                    self.bus.send(can.Message(arbitration_id=can_id, data=data,
                                              is_extended_id=False))
            msg = self.bus.recv(0.0)
            if msg is not None:
                now = self.clock()
        self.arm.advance(now)

    def serve(self, stop: threading.Event) -> None:
        """Poll until ``stop.is_set()`` (a ``threading.Event``)."""
        while not stop.is_set():
            self.poll(self.arm.sim.config.physics_dt)


class PtyLink:
    """A pseudo-terminal in raw mode whose device is linked at ``link``; we hold the master."""

    def __init__(self, link: str) -> None:
        """Open the pty and make the link (an old link there is replaced, a file is not)."""
        if os.path.lexists(link) and not os.path.islink(link):
            raise InvalidInputError(f'{link} exists and is no symbolic link: not replacing it')
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)            # no echo, no line discipline: bytes as they are
        os.set_blocking(self.master, False)
        self.device = os.ttyname(self.slave)
        self.link = link
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(self.device, link)
        self.written = 0
        self.overruns = 0                 # frames lost because nobody reads the port

    def read(self) -> bytes:
        """Return what the port has (b'' if nothing)."""
        try:
            return os.read(self.master, 4096)
        except (BlockingIOError, OSError):
            return b''

    def write(self, frame: bytes) -> None:
        """Write one frame; drop it if the port's buffer is full (nobody reads)."""
        try:
            os.write(self.master, frame)
            self.written += 1
        except (BlockingIOError, OSError):
            self.overruns += 1

    def close(self) -> None:
        """Remove the link and close the pty."""
        if os.path.islink(self.link) and os.readlink(self.link) == self.device:
            os.unlink(self.link)
        os.close(self.master)
        os.close(self.slave)


class Corruptor:
    """Flip one byte in each of the next ``count`` serial frames (of one joint, or any)."""

    def __init__(self) -> None:
        """Corrupt nothing yet."""
        self.pending = 0
        self.joint = None
        self.done = 0

    def arm(self, count: int, joint: int | None) -> None:
        """Corrupt the next ``count`` frames (of ``joint``'s replies, if given)."""
        self.pending, self.joint = count, joint

    def apply(self, can_id: int, frame: bytes) -> bytes:
        """Return ``frame``, corrupted if it is one of those asked for."""
        if self.pending <= 0 or (self.joint is not None and
                                 can_id != protocol.reply_id(self.joint)):
            return frame
        self.pending -= 1
        self.done += 1
        out = bytearray(frame)
        out[2 + self.done % 8] ^= 0x5A      # a data byte: position, flags, ... never valid
        return bytes(out)


def _parse_int(text, name):
    """Return ``text`` as an int (decimal or 0x..), or raise InvalidInputError."""
    try:
        return int(text, 0)
    except ValueError:
        raise InvalidInputError(f'{name} must be an integer, got {text!r}') from None


class SerialArm:
    """The arm behind a pty speaking the USB2CAN framing, plus the control channel."""

    def __init__(self, arm: CanArm, link: str, control_path: str) -> None:
        """Open the pty and the control socket."""
        self.arm = arm
        self.decoder = usb2can.SerialFrameDecoder(accept_ids=COMMAND_IDS)
        self.corruptor = Corruptor()
        self.pty = PtyLink(link)
        self.link = link
        self.written = 0                  # frames written on ptys closed since (unplugged)
        self.control_path = control_path
        if os.path.lexists(control_path):
            os.unlink(control_path)
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(control_path)
        self.listener.listen(4)
        self.clients = {}                 # socket -> bytes received so far
        self.running = True

    def close(self) -> None:
        """Close everything and remove the link and the socket."""
        for client in list(self.clients):
            client.close()
        self.listener.close()
        if os.path.exists(self.control_path):
            os.unlink(self.control_path)
        if self.pty is not None:
            self.pty.close()

    def run(self) -> None:
        """Serve until ``running`` is cleared (by a signal)."""
        dt = self.arm.sim.config.physics_dt
        while self.running:
            fds = [self.listener] + list(self.clients) + \
                ([self.pty.master] if self.pty is not None else [])
            try:
                ready, _, _ = select.select(fds, [], [], dt)
            except InterruptedError:
                continue
            if self.listener in ready:
                client, _ = self.listener.accept()
                self.clients[client] = b''
            for client in [c for c in self.clients if c in ready]:
                self.on_client(client)
            # Always drain the port before the watchdog looks (advance): frames that came while
            # this process was held up are taken as arriving now, not as missing.
            now = time.monotonic()
            chunk = self.pty.read() if self.pty is not None else b''
            if chunk:
                self.on_serial(chunk, now)
            self.arm.advance(now)

    def on_serial(self, chunk: bytes, now: float) -> None:
        """Answer every frame in ``chunk``."""
        for can_id, data in self.decoder.feed(chunk, now):
            for reply_id, reply in self.arm.receive(can_id, data, now):
                frame = usb2can.encode_serial_frame(reply_id, reply)
                if self.pty is not None:
                    self.pty.write(self.corruptor.apply(reply_id, frame))

    def on_client(self, client: socket.socket) -> None:
        """Read from a control client; answer each complete line."""
        try:
            data = client.recv(4096)
        except OSError:
            data = b''
        if not data:
            client.close()
            del self.clients[client]
            return
        buffer = self.clients[client] + data
        *lines, rest = buffer.split(b'\n')
        self.clients[client] = rest
        for line in lines:
            try:
                answer = {'ok': True, **self.command(line.decode().split())}
            except (InvalidInputError, UnicodeDecodeError) as err:
                answer = {'ok': False, 'error': str(err)}
            try:
                client.sendall((json.dumps(answer) + '\n').encode())
            except OSError:
                pass

    def command(self, words: list[str]) -> dict:
        """Carry out one control command; return what to answer."""
        now = time.monotonic()
        if len(words) == 2 and words[0] == 'inputs':
            self.arm.set_inputs(_parse_int(words[1], 'BITS'))
            return {}
        if words == ['frames']:
            return {'now': now, 'modules': self.arm.take_frames()}
        if words == ['unplug']:
            if self.pty is not None:
                self.written += self.pty.written
                self.pty.close()
                self.pty = None
            return {}
        if words == ['replug']:
            if self.pty is None:
                self.pty = PtyLink(self.link)
                self.decoder = usb2can.SerialFrameDecoder(accept_ids=COMMAND_IDS)
            return {'pty': self.pty.device}
        if words == ['status']:
            pty = self.pty
            return {**self.arm.status(), 'pty': pty.device if pty else None,
                    'plugged': pty is not None,
                    'frames_out': self.written + (pty.written if pty else 0),
                    'overruns': pty.overruns if pty else 0,
                    'corrupted': self.corruptor.done, 'corrupt_pending': self.corruptor.pending,
                    'serial_dropped': self.decoder.dropped}
        if len(words) in (3, 4) and words[0] == 'flags' and words[3:] in ([], ['sticky']):
            joint = _parse_int(words[1], 'JOINT')
            self.arm.inject_flags(joint, _parse_int(words[2], 'FLAGS'), now, words[3:] != [])
            return {}
        if len(words) == 3 and words[0] == 'silent' and words[2] in ('on', 'off'):
            self.arm.set_silent(_parse_int(words[1], 'JOINT'), words[2] == 'on')
            return {}
        if len(words) in (2, 3) and words[0] == 'corrupt':
            count = _parse_int(words[1], 'COUNT')
            joint = _parse_int(words[2], 'JOINT') if len(words) == 3 else None
            if count < 0 or (joint is not None and joint not in protocol.JOINTS):
                raise InvalidInputError(f'corrupt COUNT [JOINT]: COUNT >= 0, JOINT in 1..6; '
                                        f'got {words[1:]}')
            self.corruptor.arm(count, joint)
            return {}
        raise InvalidInputError(
            f'unknown command {" ".join(words)!r}: status | flags JOINT FLAGS [sticky] | '
            f'silent JOINT on|off | corrupt COUNT [JOINT] | inputs BITS | frames | unplug | '
            f'replug')


def control(path: str, line: str, timeout: float = 5.0) -> dict:
    """Send one command to the control socket at ``path``; return its answer."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(timeout)
        sock.connect(path)
        sock.sendall(line.strip().encode() + b'\n')
        answer = b''
        while not answer.endswith(b'\n'):
            chunk = sock.recv(65536)
            if not chunk:
                break
            answer += chunk
    return json.loads(answer.decode())


def parse_args(argv: Optional[list[str]]) -> argparse.Namespace:
    """Return the command line's options."""
    parser = argparse.ArgumentParser(
        prog='can_sim', description='The Mover6 at CAN level on a pseudo-terminal speaking the '
        'CPR USB2CAN framing (see the module docstring of sim_bridge.can_sim).')
    parser.add_argument('--link', help='make the pty reachable at this path (required)')
    parser.add_argument('--control', help='control socket path (default: LINK.control)')
    parser.add_argument('--limit-set', default='hardware', choices=LIMIT_SETS,
                        help='joint limits of the simulated arm (default: hardware)')
    parser.add_argument('--joints-file', default=JOINTS_YAML,
                        help="joint configuration YAML (default: the package's "
                        'config/mover6_joints.yaml, as the driver)')
    parser.add_argument('--home', type=float, nargs=6, metavar='Q',
                        help='joint positions at power-up [rad] (default: zeros)')
    parser.add_argument('--watchdog-timeout', type=float, default=ModuleTiming.watchdog_timeout,
                        help='[s] without a set-point before 0x08 (default: %(default)s)')
    parser.add_argument('--lag-limit', type=float, default=ModuleTiming.lag_limit,
                        help='[rad] position lag before 0x10 (default: %(default)s)')
    parser.add_argument('--command-replies', choices=('on', 'off'), default='on',
                        help='on: the modules answer every command they take; off: '
                        'only set-points, the worst a driver may meet (default: %(default)s)')
    parser.add_argument('--priority', type=int, default=SIM_PRIORITY,
                        help='SCHED_FIFO priority of the simulated modules where the system '
                        'allows it, 0 = normal scheduling (default: %(default)s, above the '
                        "driver's cycle_priority: real modules never wait for a CPU)")
    parser.add_argument('--send', nargs='+', metavar=('PATH', 'WORD'),
                        help='send one control command to a running can_sim and print the '
                        'answer, e.g. --send /tmp/mover6-can.control status')
    args = parser.parse_args(argv)
    if args.send is None and not args.link:
        parser.error('--link is required')
    return args


def main(argv: Optional[list[str]] = None) -> int:
    """Run the simulated arm on a pty until SIGINT or SIGTERM; or send one control command."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.send is not None:
        if len(args.send) < 2:
            print('can_sim: --send PATH COMMAND...', file=sys.stderr)
            return 2
        answer = control(args.send[0], ' '.join(args.send[1:]))
        print(json.dumps(answer))
        return 0 if answer.get('ok') else 1
    try:
        timing = ModuleTiming(watchdog_timeout=args.watchdog_timeout, lag_limit=args.lag_limit)
        arm = build_arm(args.limit_set, args.joints_file, args.home, timing,
                        args.command_replies == 'on')
        server = SerialArm(arm, args.link, args.control or args.link + '.control')
    except (InvalidInputError, OSError) as err:
        print(f'can_sim: {err}', file=sys.stderr)
        return 2

    def stop(*_):
        server.running = False

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    if args.priority > 0:
        ok, message = run_at_priority(args.priority)
        print(f'can_sim: {message if ok else "normal scheduling: " + message}', flush=True)
    print(f'can_sim: ready on {args.link} ({server.pty.device}), control {server.control_path}',
          flush=True)
    try:
        server.run()
    finally:
        server.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
