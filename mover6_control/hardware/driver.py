"""
The Mover6 arm driver without ROS: joint velocities in, position set-points on the CAN bus out.

One ``ArmDriver`` owns the bus. Each cycle (``step``, 50 ms by default; ``start`` runs it on one
control thread) it reads every reply that arrived, updates each joint's state, integrates the
commanded joint velocities into set-points and sends one set-point per module. The differences
from the vendor's driver (``MotorModule::WriteLoop``, ``Joint::OnWrite`` in cpr_robot) are on
purpose:

- the set-point starts at the measured position, and keeps tracking it whenever a joint is not
  enabled (after start, a reset, a fault, referencing, set zero): never a jump. Before the first
  reply the position is unknown, so the first frames are a ``disable`` to every module and then
  set-points a disabled module cannot act on (the vendor streams set-point 0 to a module that may
  be enabled);
- the set-point is integrated in fractional ticks (a slow wrist command still moves J5 and J6),
  clamped to the joint's tick limits and to the measured position plus or minus ``max_lag``;
- a command older than ``command_timeout`` stops the integration at the next cycle: the arm
  holds where it is (the vendor keeps the last command forever);
- any error flag on any joint, a joint not enabled, or a module silent for ``silent_cycles``
  cycles holds the whole arm (velocity zero, set-points frozen), with the reason in the report;
  a silent module is a latched ``fault`` until ``reset``;
- ``close`` disables every module before the bus is shut down.

What the bus brings that is not a reply of one of the joints' modules is dropped and counted by
its reason (``ArmReport.bad_frames``), never decoded as a position: an unknown or extended ID, a
remote or error frame, a reply of the wrong length, a command frame of another master on the
bus. A well-formed reply whose position jumps further than the joint can have moved since its last
reply (``max_lag`` plus twice its maximum speed over the time between the two) while the driver
drives it is dropped too ('position_jump'): the set-point never follows it, and a joint whose
replies keep jumping goes silent and faults, so the arm holds.

The control thread (``start``) sleeps to absolute deadlines on ``clock`` (an overrun skips, never
bursts) and, with ``priority`` 1..99, runs at SCHED_FIFO where the system allows it
(``mover6_control.realtime``, the controller's tick uses the same); the reports it produces go
to ``on_cycle``, which must hand them over without waiting (the node publishes on a thread of
its own).

Per joint and for the arm the state is a ``ModuleState``: disconnected (no reply yet), connected
(replying, motor not enabled), error (a flag other than "motor not enabled"), enabled, referenced
(enabled and referenced), fault (silent). The arm's state is its worst joint's.

Requests (``request``: reset, enable, disable, reference, set_zero) are sent by the control
thread in bus order; enable, reference and set zero go twice, 20 ms apart, as the vendor does.
A request is answered once every addressed module confirms it in a reply received after it was
sent (or refused at once, or timed out), with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
import threading
import time
from typing import Callable, Optional, Sequence

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.scaling import JointScale
from mover6_control.realtime import run_at_priority


class ModuleState(StrEnum):
    """The state of a joint's motor module, and of the arm (its worst joint's)."""

    DISCONNECTED = 'disconnected'
    CONNECTED = 'connected'
    ERROR = 'error'
    ENABLED = 'enabled'
    REFERENCED = 'referenced'
    FAULT = 'fault'


S = ModuleState
# Worst first: the arm takes the first of these that any joint is in.
_ARM_ORDER = (S.FAULT, S.DISCONNECTED, S.ERROR, S.CONNECTED, S.ENABLED, S.REFERENCED)
# The states in which a module follows its set-points.
FOLLOWING = (S.ENABLED, S.REFERENCED)
REPEAT_DELAY = 0.02
"""Delay between the two frames of enable, start referencing and set zero [s]."""


@dataclass(frozen=True)
class JointReport:
    """One joint at one cycle: ``q`` [rad], ``qd`` [rad/s], ``lag`` = set-point - q [rad]."""

    name: str
    state: str
    q: float
    qd: float
    setpoint: float
    lag: float
    flags: int
    flag_names: tuple[str, ...]
    referenced: bool
    silent_cycles: int
    replies: int


@dataclass(frozen=True)
class ArmReport:
    """The arm at one cycle; ``hold`` is why it does not move ('' when it may)."""

    time: float
    state: str
    hold: str
    joints: tuple[JointReport, ...]
    period: float
    frames_dropped: int
    frames_bad: int
    tx_errors: int
    bus_error: str
    bad_frames: tuple[tuple[str, int], ...] = ()
    last_bad_frame: str = ''


class Request:
    """A command to the modules; ``wait`` blocks until it is confirmed, refused or timed out."""

    def __init__(self, kind: str, joints: tuple[int, ...], timeout: float) -> None:
        self.kind = kind
        self.joints = joints
        self.timeout = timeout
        self.sent = None
        self.ok = None
        self.reason = ''
        self._done = threading.Event()

    def finish(self, ok: bool, reason: str) -> None:
        """Record the answer and wake the waiter (first answer wins)."""
        if self.ok is None:
            self.ok, self.reason = ok, reason
            self._done.set()

    def wait(self, timeout: Optional[float] = None) -> tuple[bool, str]:
        """Return (ok, reason) once answered; (False, reason) if ``timeout`` [s] passes first."""
        if not self._done.wait(timeout):
            return False, f'{self.kind}: no answer from the driver within {timeout} s'
        return self.ok, self.reason


class _Joint:
    """The driver's mutable record of one joint (control thread only, under the lock)."""

    def __init__(self, scale: JointScale) -> None:
        self.scale = scale
        self.reply: Optional[p.Reply] = None
        self.reply_time = None
        self.replies = 0
        self.ticks = None          # measured, offset removed
        self.qd = 0.0
        self.setpoint = None       # [ticks, float]
        self.velocity = 0.0        # commanded, [rad/s]
        self.silent = 0
        self.fault = False
        self.track = True          # set-point follows the measured position
        self.counter = 0
        self.outputs = 0

    def state(self) -> str:
        if self.fault:
            return S.FAULT
        if self.reply is None:
            return S.DISCONNECTED
        flags = self.reply.error_flags
        if flags & ~0x04:
            return S.ERROR
        if flags & 0x04:
            return S.CONNECTED
        return S.REFERENCED if self.reply.referenced else S.ENABLED


class ArmDriver:
    """
    Drive the modules on ``bus`` for ``joints`` (``scaling.load_joints``), one cycle per ``step``.

    ``cycle`` [s], ``command_timeout`` [s], ``max_lag`` [rad] and ``silent_cycles`` as in the
    module docstring; ``limit_set`` names the joint limits the set-points are clamped to (always
    within the hardware ones); ``firmware`` names the error-flag table. ``clock`` [s] is only used
    by the control thread (``start``) and by ``request``; ``step`` takes the time as an argument.
    ``on_cycle``, if given, gets every cycle's ``ArmReport`` on the control thread. ``priority``
    (0 = normal scheduling, 1..99 SCHED_FIFO where allowed) is the control thread's;
    ``scheduling`` says what it got.
    """

    def __init__(self, bus: can.BusABC, joints: Sequence[JointScale], *, cycle: float = 0.05,
                 command_timeout: float = 0.2, max_lag: float = 0.2, silent_cycles: int = 3,
                 limit_set: str = 'hardware', firmware: str = 'mover6',
                 clock: Callable[[], float] = time.monotonic,
                 on_cycle: Optional[Callable[[ArmReport], None]] = None,
                 priority: int = 0) -> None:
        for name, value in (('cycle', cycle), ('command_timeout', command_timeout),
                            ('max_lag', max_lag)):
            if not value > 0.0:
                raise InvalidInputError(f'{name} must be positive, got {value!r}')
        if int(silent_cycles) < 1:
            raise InvalidInputError(f'silent_cycles must be >= 1, got {silent_cycles!r}')
        p.flag_names(0, firmware)
        self.bus = bus
        self._joints = [_Joint(j) for j in joints]
        for j in self._joints:
            j.scale.tick_limits(limit_set)
        self.cycle = float(cycle)
        self.command_timeout = float(command_timeout)
        self.max_lag = float(max_lag)
        self.silent_cycles = int(silent_cycles)
        self.limit_set = limit_set
        self.firmware = firmware
        self.clock = clock
        self.on_cycle = on_cycle
        self._lock = threading.RLock()
        self._command = None          # (velocities [rad/s], time [s])
        self._scheduled = []          # (due [s], can_id, data)
        self._requests = []
        self._last_step = None
        self._started = False
        self._report = None
        self._bad = 0
        self._bad_reasons = {}        # reason -> frames dropped for it
        self._last_bad = ''
        self.priority = int(priority)
        self.scheduling = 'not started'
        self._tx_errors = 0
        self._bus_error = ''
        self._stop = threading.Event()
        self._thread = None

    @property
    def names(self) -> tuple[str, ...]:
        """Return the joint names, in module order."""
        return tuple(j.scale.name for j in self._joints)

    @property
    def report(self) -> Optional[ArmReport]:
        """Return the last cycle's report, None before the first cycle."""
        return self._report

    # --- commands (any thread) ---

    def set_velocity(self, qd: Sequence[float], now: Optional[float] = None) -> None:
        """
        Command joint velocities ``qd`` [rad/s], one per joint, each clipped to its max speed.

        InvalidInputError on a wrong length or a non-finite value; the previous command stands.
        """
        values = [float(v) for v in qd]
        if len(values) != len(self._joints):
            raise InvalidInputError(f'need {len(self._joints)} joint velocities, '
                                    f'got {len(values)}')
        if not all(v == v and abs(v) != float('inf') for v in values):
            raise InvalidInputError(f'joint velocities must be finite, got {values}')
        clipped = [max(-j.scale.max_speed, min(j.scale.max_speed, v))
                   for j, v in zip(self._joints, values)]
        with self._lock:
            self._command = (clipped, self.clock() if now is None else now)

    def set_outputs(self, joint: int, bits: int) -> None:
        """Set the digital outputs (0..255) sent to module ``joint`` (1..6) with its set-points."""
        p.command_id(joint)
        if isinstance(bits, bool) or not isinstance(bits, int) or not 0 <= bits <= 0xFF:
            raise InvalidInputError(f'digital outputs must be an int in 0..255, got {bits!r}')
        with self._lock:
            self._joints[joint - 1].outputs = bits

    def request(self, kind: str, joints: Optional[Sequence[int]] = None,
                timeout: float = 2.0) -> Request:
        """
        Queue ``kind`` (reset, enable, disable, reference, set_zero) for ``joints`` (default all).

        Referencing and set zero are refused while the arm moves; referencing needs its joint
        enabled, set zero its joints disabled. The control thread sends the frames at its next
        cycle.
        """
        if kind not in p.COMMAND_FRAMES:
            raise InvalidInputError(f'request must be one of {sorted(p.COMMAND_FRAMES)}, '
                                    f'got {kind!r}')
        targets = tuple(range(1, len(self._joints) + 1)) if joints is None else tuple(joints)
        for n in targets:
            if n not in range(1, len(self._joints) + 1):
                raise InvalidInputError(f'joint must be in 1..{len(self._joints)}, got {n!r}')
        req = Request(kind, targets, float(timeout))
        with self._lock:
            if kind in ('reference', 'set_zero') and self._moving():
                req.finish(False, f'{kind} refused: the arm is moving')
            elif kind == 'set_zero' and any(
                    self._joints[n - 1].state() in FOLLOWING for n in targets):
                req.finish(False, 'set_zero refused: disable the motors first (an enabled '
                                  'module would follow a set-point sent before the zero)')
            elif kind == 'reference' and any(
                    self._joints[n - 1].state() not in FOLLOWING for n in targets):
                req.finish(False, 'reference refused: the joint must be enabled first')
            else:
                self._requests.append(req)
        return req

    # --- the cycle ---

    def step(self, now: float) -> ArmReport:
        """Run one cycle at time ``now`` [s]: read replies, update, integrate, send."""
        with self._lock:
            dt = self.cycle if self._last_step is None else max(0.0, now - self._last_step)
            period = 0.0 if self._last_step is None else now - self._last_step
            self._last_step = now
            if not self._started:
                self._started = True
                for n in range(1, len(self._joints) + 1):
                    self._send(p.command_id(n), p.DISABLE)
            self._read(now)
            self._send_requests(now)
            busy = {n for r in self._requests if r.kind in ('reference', 'set_zero')
                    for n in r.joints}
            hold = self._hold_reason(busy)
            fresh = self._command is not None and now - self._command[1] <= self.command_timeout
            command = self._command[0] if fresh else [0.0] * len(self._joints)
            for n, (j, v) in enumerate(zip(self._joints, command), start=1):
                if n in busy:
                    j.track = True               # the module moves itself: follow it
                self._integrate(j, v, dt, frozen=bool(hold))
            for n, j in enumerate(self._joints, start=1):
                wire = j.scale.to_wire(round(j.setpoint) if j.setpoint is not None else 0)
                self._send(p.command_id(n), p.encode_setpoint(wire, j.counter, j.outputs))
                j.counter = (j.counter + 1) & 0xFF
            self._send_due(now)
            self._check_requests(now)
            self._report = self._make_report(now, hold, period)
        if self.on_cycle is not None:
            self.on_cycle(self._report)
        return self._report

    def _read(self, now: float) -> None:
        fresh = set()
        while True:
            try:
                msg = self.bus.recv(timeout=0.0)
            except can.CanError as err:
                self._bus_error = f'receive failed: {err}'
                break
            if msg is None:
                break
            reason = ''
            if msg.is_error_frame or msg.is_remote_frame:
                reason = 'remote_or_error_frame'
            elif msg.is_extended_id:
                reason = 'extended_id'
            else:
                try:
                    joint, is_reply = p.joint_of_id(msg.arbitration_id)
                except p.ProtocolError:
                    reason = 'unknown_id'
                else:
                    if not is_reply:
                        reason = 'command_of_another_master'
                    elif joint > len(self._joints):
                        reason = 'unknown_id'
            if not reason:
                try:
                    reply = p.decode_reply(bytes(msg.data[:msg.dlc]))
                except p.ProtocolError:
                    reason = 'wrong_length'
            if not reason:
                j = self._joints[joint - 1]
                ticks = j.scale.from_wire(reply.position)
                if not self._plausible(j, ticks, now):
                    reason = 'position_jump'
            if reason:
                self._refuse_frame(msg, reason)
                continue
            if j.ticks is not None and j.reply_time is not None and now > j.reply_time:
                j.qd = j.scale.to_rad(ticks - j.ticks) / (now - j.reply_time)
            j.reply, j.ticks, j.reply_time = reply, ticks, now
            j.replies += 1
            fresh.add(joint)
        for n, j in enumerate(self._joints, start=1):
            if n in fresh:
                j.silent = 0
            elif j.reply is not None:
                j.silent += 1
                j.qd = 0.0
                if j.silent >= self.silent_cycles:
                    j.fault = True

    def _refuse_frame(self, msg: can.Message, reason: str) -> None:
        self._bad += 1
        self._bad_reasons[reason] = self._bad_reasons.get(reason, 0) + 1
        data = bytes(msg.data[:msg.dlc]).hex(' ')
        self._last_bad = f'{reason}: id 0x{msg.arbitration_id:X} dlc {msg.dlc} [{data}]'

    def _plausible(self, j: _Joint, ticks: int, now: float) -> bool:
        """Return False for a reply whose position the joint cannot have reached."""
        if j.ticks is None or j.reply_time is None:
            return True
        if not j.fault and (j.track or j.state() not in FOLLOWING):
            return True            # not driven: the set-point follows the measured position
        # Driven, or latched silent (its set-point frozen at the last reading until a reset).
        reach = self.max_lag + 2.0 * j.scale.max_speed * max(now - j.reply_time, self.cycle)
        return abs(ticks - j.ticks) <= reach * abs(j.scale.ticks_per_rad) + 2

    def _hold_reason(self, busy: set) -> str:
        if busy:
            return f'joints {sorted(busy)}: referencing or setting zero'
        for j in self._joints:
            state = j.state()
            if state == S.FAULT:
                return f'{j.scale.name}: module silent for {j.silent} cycles'
            if state == S.DISCONNECTED:
                return f'{j.scale.name}: no reply from its module yet'
            if state == S.ERROR:
                names = ', '.join(p.flag_names(j.reply.error_flags & ~0x04, self.firmware))
                return f'{j.scale.name}: error flags {names}'
            if state == S.CONNECTED:
                return f'{j.scale.name}: motor not enabled'
        return ''

    def _integrate(self, j: _Joint, v: float, dt: float, frozen: bool) -> None:
        if j.ticks is None:
            return
        if j.track or j.setpoint is None or j.state() not in FOLLOWING:
            j.setpoint = float(j.ticks)      # never a jump: start from where the joint is
            j.track = j.state() not in FOLLOWING
            j.velocity = 0.0
            return
        if frozen:
            j.velocity = 0.0
            return
        if v == 0.0:
            # At rest the set-point is the whole tick on the wire (nothing sent changes), so
            # a later move of whole ticks lands on whole ticks, not a rounding away from them.
            j.setpoint = float(round(j.setpoint))
            j.velocity = 0.0
            return
        lo, hi = j.scale.tick_limits(self.limit_set)
        lag = self.max_lag * abs(j.scale.ticks_per_rad)
        target = j.setpoint + v * dt * j.scale.ticks_per_rad
        target = min(max(target, j.ticks - lag, lo), j.ticks + lag, hi)
        j.velocity = j.scale.to_rad(target - j.setpoint) / dt if dt > 0 else 0.0
        j.setpoint = target

    def _moving(self) -> bool:
        command = self._command
        live = command is not None and self.clock() - command[1] <= self.command_timeout and \
            any(v != 0.0 for v in command[0])
        return live or any(j.velocity != 0.0 for j in self._joints)

    def _send(self, can_id: int, data: bytes) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=can_id, is_extended_id=False, data=data))
        except can.CanError as err:
            self._tx_errors += 1
            self._bus_error = f'send failed: {err}'

    def _send_requests(self, now: float) -> None:
        for req in self._requests:
            if req.sent is not None:
                continue
            req.sent = now
            data = p.COMMAND_FRAMES[req.kind]
            for n in req.joints:
                self._send(p.command_id(n), data)
                if req.kind in ('enable', 'reference', 'set_zero'):
                    self._scheduled.append((now + REPEAT_DELAY, p.command_id(n), data))
                if req.kind in ('reset', 'reference', 'set_zero', 'enable', 'disable'):
                    j = self._joints[n - 1]
                    j.track = True
                    if req.kind == 'reset':
                        j.fault, j.silent = False, 0

    def send_due(self, now: float) -> None:
        """Send the repeated frames that are due at ``now`` [s] (the control thread's job)."""
        with self._lock:
            self._send_due(now)

    def _send_due(self, now: float) -> None:
        due = [s for s in self._scheduled if s[0] <= now]
        self._scheduled = [s for s in self._scheduled if s[0] > now]
        for _, can_id, data in due:
            self._send(can_id, data)

    def next_due(self) -> Optional[float]:
        """Return when the next repeated frame is due [s], or None."""
        with self._lock:
            return min((s[0] for s in self._scheduled), default=None)

    def _confirmed(self, req: Request) -> str:
        """Return '' once every addressed module confirms ``req``, else what is missing."""
        for n in req.joints:
            j = self._joints[n - 1]
            if j.reply is None or j.reply_time is None or j.reply_time <= req.sent:
                return f'{j.scale.name}: no reply since the command'
            flags = j.reply.error_flags
            missing = {
                'reset': flags & ~0x04 and 'error flags still set: ' + ', '.join(
                    p.flag_names(flags & ~0x04, self.firmware)),
                'enable': flags and 'flags ' + ', '.join(p.flag_names(flags, self.firmware)),
                'disable': not flags & 0x04 and 'motor still enabled',
                'reference': not j.reply.referenced and 'not referenced yet',
                'set_zero': abs(j.ticks) > 1 and f'position {j.ticks} ticks, not zero',
            }[req.kind]
            if missing:
                return f'{j.scale.name}: {missing}'
        return ''

    def _check_requests(self, now: float) -> None:
        for req in list(self._requests):
            missing = self._confirmed(req)
            if not missing:
                req.finish(True, f'{req.kind}: confirmed by joints {list(req.joints)}')
            elif now - req.sent >= req.timeout:
                req.finish(False, f'{req.kind}: not confirmed within {req.timeout} s ({missing})')
            if req.ok is not None:
                self._requests.remove(req)

    def _make_report(self, now: float, hold: str, period: float) -> ArmReport:
        joints = []
        for j in self._joints:
            q = j.scale.to_rad(j.ticks) if j.ticks is not None else float('nan')
            sp = j.scale.to_rad(j.setpoint) if j.setpoint is not None else q
            flags = j.reply.error_flags if j.reply is not None else 0
            joints.append(JointReport(
                name=j.scale.name, state=j.state(), q=q, qd=j.qd, setpoint=sp, lag=sp - q,
                flags=flags, flag_names=p.flag_names(flags, self.firmware),
                referenced=bool(j.reply and j.reply.referenced), silent_cycles=j.silent,
                replies=j.replies))
        state = next(s for s in _ARM_ORDER if any(r.state == s for r in joints))
        return ArmReport(time=now, state=state, hold=hold, joints=tuple(joints), period=period,
                         frames_dropped=int(getattr(self.bus, 'dropped', 0)),
                         frames_bad=self._bad, tx_errors=self._tx_errors,
                         bus_error=self._bus_error,
                         bad_frames=tuple(sorted(self._bad_reasons.items())),
                         last_bad_frame=self._last_bad)

    # --- the control thread ---

    def start(self) -> None:
        """Start the control thread: one ``step`` every ``cycle`` on ``clock``."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='mover6_driver', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        if self.priority > 0:
            ok, message = run_at_priority(self.priority)
            self.scheduling = message if ok else f'normal scheduling: {message}'
        else:
            self.scheduling = 'normal scheduling (priority 0)'
        next_cycle = self.clock()
        while not self._stop.is_set():
            now = self.clock()
            if now >= next_cycle:
                self.step(now)
                next_cycle += self.cycle
                if next_cycle < now:                 # overran: skip, do not burst
                    next_cycle = now + self.cycle
            else:
                self.send_due(now)
            wake = min(next_cycle, self.next_due() or next_cycle)
            self._stop.wait(max(0.0, wake - self.clock()))

    def close(self) -> None:
        """Stop the control thread, disable every module, shut the bus down."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        with self._lock:
            for n in range(1, len(self._joints) + 1):
                self._send(p.command_id(n), p.DISABLE)
            for req in self._requests:
                req.finish(False, f'{req.kind}: the driver shut down')
            self._requests = []
        self.bus.shutdown()
