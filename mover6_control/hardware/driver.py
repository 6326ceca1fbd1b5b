"""
The Mover6 arm driver without ROS: joint velocities in, position set-points on the CAN bus out.

One ``ArmDriver`` owns the bus. Each cycle (``step``, 50 ms by default; ``start`` runs it on one
control thread) it reads every reply that arrived, updates each joint's state, integrates the
commanded joint velocities into set-points and queues one set-point per module; the frames go
out in order, ``frame_gap`` apart (``outbox``). The differences from the vendor's driver
(``MotorModule::WriteLoop``, ``Joint::OnWrite`` in cpr_robot) are on purpose. The first is one
rule: **no set-point that is not where the joint is reaches a module that is, or is about to be,
enabled.** So:

- before a module has answered, it gets ``disable`` (which moves nothing; a module that answers
  every command tells its position in the reply). Only a module that still has not answered
  after ``PROBE_CYCLES`` cycles gets a set-point, and then right behind a ``disable``, so it is
  disabled when the set-point arrives (the vendor streams set-point 0 to a module that may be
  enabled);
- while a joint is not enabled (after start, a reset, a fault, referencing, set zero) its
  set-point is its measured position; ``enable`` goes out only once every module has answered a
  set-point at its measured position (``driver_requests``), so a module that keeps its last
  set-point while disabled goes nowhere when enabled; enable is all six modules or none;
- motion after an enable starts only from a command that arrives after it: a JointJog stream
  that was live before it moves nothing;
- the set-point is integrated in fractional ticks (a slow wrist command still moves J5 and J6),
  clamped to the joint's tick limits and to the measured position plus or minus ``max_lag``; a
  clamp only shortens a cycle's step (``setpoints``): a joint found outside its limits moves only
  inward, at the commanded speed;
- a command older than ``command_timeout`` stops the integration at the next cycle: the arm
  holds where it is (the vendor keeps the last command forever);
- any error flag on any joint, a joint not enabled, a missed reply, a joint that requires
  referencing and is not referenced, or a lost reference (``driver_state``) holds the whole arm
  (velocity zero, set-points frozen: the driver does not know where the joint is, it does not
  guess), with the reason in the report; it moves on when the reply comes, and a module silent
  for ``silent_cycles`` cycles in a row is a latched ``fault`` until ``reset``;
- confirmations (enable, reset, referencing, set zero) count only replies that echo a set-point
  sent after the command (``driver_replies``);
- ``close`` disables every module before the bus is shut down, and never hangs (the thread is
  joined with a timeout, a write never blocks longer than the adapter's write timeout);
- a link that goes (the USB2CAN adapter pulled: ``link.LinkWatch``) holds the arm with the
  reason (the modules stop on their own watchdog), answers every pending request with a refusal,
  forgets every position, and reopens the port with back-off; once it is back the driver starts
  over as at start (``disable`` to every module, each position read again) and stays not enabled
  until a reset and an enable are asked for;
- a control thread that dies reports it: its last report is a ``fault`` with the exception
  (``thread_error``), not silence.

The gripper (joint 4's digital outputs, ``set_gripper``) reports nothing back: the report carries
its estimated gap (``gripper.GripperModel``) and the arm's digital inputs (joint 1's replies).

Observability that cannot move the arm: ``frame_log`` (a ``can.Listener``, e.g. python-can's
candump log writer from ``bus.open_frame_log``) gets every frame sent and read, with its
direction; ``listen_only`` sends nothing at all (no disable at start, no set-point, every request
refused): it decodes and reports what the modules answer to another master on the bus.

What the bus brings that is not a fresh reply of one of the joints' modules is refused and
counted by its reason (``ArmReport.bad_frames``, ``driver_replies``).

The control thread (``start``) sleeps to absolute deadlines on ``clock`` (an overrun skips, never
bursts) and, with ``priority`` 1..99, runs at SCHED_FIFO where the system allows it
(``mover6_control.realtime``, the controller's tick uses the same); the reports it produces go
to ``on_cycle``, which must hand them over without waiting (the node publishes on a thread of
its own).

The driver is built from parts it makes in its constructor, each a class a test can build alone:
``JointRecord`` per joint (``driver_state``: the joint's record and state machine), an
``Outbox`` (the frames in order, ``frame_gap`` apart), a ``ReplyIntake`` (the bus intake) and
``Requests`` (reset, enable, disable, reference and set zero, and their confirmation); the
set-point integrator is the function ``setpoints.integrate``.
"""

from __future__ import annotations

from dataclasses import replace
import threading
import time
from typing import Callable, Optional, Sequence

import can
from mover6_control.errors import InvalidInputError, NonFiniteError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver_replies import ReplyIntake
from mover6_control.hardware.driver_requests import Request, Requests
from mover6_control.hardware.driver_state import (
    arm_state, ArmReport, hold_reason, joint_report, JointRecord, ModuleState)
from mover6_control.hardware.gripper import GripperModel
from mover6_control.hardware.link import LinkWatch
from mover6_control.hardware.outbox import Outbox
from mover6_control.hardware.scaling import JointScale
from mover6_control.hardware.setpoints import integrate
from mover6_control.realtime import run_at_priority

PROBE_CYCLES = 2
"""Cycles of ``disable`` alone before a silent module is polled with a set-point behind one."""
FRAME_GAP = 0.005
"""[s] between two frames the driver sends: the vendor's (``Bus.cpp``, CPRog's configuration)."""


class ArmDriver:
    """
    Drive the modules on ``bus`` for ``joints`` (``scaling.load_joints``), one cycle per ``step``.

    ``cycle`` [s], ``command_timeout`` [s], ``max_lag`` [rad], ``silent_cycles`` and
    ``frame_gap`` [s] as in the module docstring; ``limit_set`` names the joint limits the
    set-points are clamped to (always within the hardware ones); ``firmware`` names the
    error-flag table. ``clock`` [s] is only used by the control thread (``start``) and by
    ``request``; ``step`` takes the time as an argument. ``on_cycle``, if given, gets every
    cycle's ``ArmReport`` on the control thread. ``priority`` (0 = normal scheduling, 1..99
    SCHED_FIFO where allowed) is the control thread's; ``scheduling`` says what it got.
    ``frame_log`` and ``listen_only`` as in the module docstring (the log is stopped by
    ``close``).
    """

    def __init__(self, bus: can.BusABC, joints: Sequence[JointScale], *, cycle: float = 0.05,
                 command_timeout: float = 0.2, max_lag: float = 0.2, silent_cycles: int = 6,
                 frame_gap: float = FRAME_GAP, limit_set: str = 'hardware',
                 firmware: str = 'mover6', clock: Callable[[], float] = time.monotonic,
                 on_cycle: Optional[Callable[[ArmReport], None]] = None,
                 priority: int = 0, frame_log: Optional[can.Listener] = None,
                 listen_only: bool = False) -> None:
        for name, value in (('cycle', cycle), ('command_timeout', command_timeout),
                            ('max_lag', max_lag)):
            if not value > 0.0:
                raise InvalidInputError(f'{name} must be positive, got {value!r}')
        if int(silent_cycles) < 1:
            raise InvalidInputError(f'silent_cycles must be >= 1, got {silent_cycles!r}')
        if not 0.0 <= frame_gap < cycle / 8:
            raise InvalidInputError(f'frame_gap must be in [0, cycle / 8), got {frame_gap!r}')
        p.flag_names(0, firmware)
        self.bus = bus
        self._joints = tuple(JointRecord(j) for j in joints)
        for j in self._joints:
            j.scale.tick_limits(limit_set)
        self.listen_only = bool(listen_only)
        self.frame_log = frame_log
        self._outbox = Outbox(bus, frame_gap, frame_log)
        self._intake = ReplyIntake(self._joints, self._outbox, silent_cycles, frame_log,
                                   self.listen_only)
        self._requests = Requests(self._joints, self._outbox, firmware)
        self.link = LinkWatch(bus)
        self.gripper = GripperModel()
        self.thread_error = ''
        self.cycle = float(cycle)
        self.command_timeout = float(command_timeout)
        self.max_lag = float(max_lag)
        self.limit_set = limit_set
        self.firmware = firmware
        self.clock = clock
        self.on_cycle = on_cycle
        self._lock = threading.RLock()
        self._command = None          # (velocities [rad/s], time [s])
        self._last_step = None
        self._started = False
        self._report = None
        self.priority = int(priority)
        self.scheduling = 'not started'
        self._stop = threading.Event()
        self._thread = None

    @property
    def names(self) -> tuple[str, ...]:
        """Return the joint names, in module order."""
        return tuple(j.scale.name for j in self._joints)

    @property
    def joint_scales(self) -> tuple[JointScale, ...]:
        """Return the joints' scaling (and referencing), in module order."""
        return tuple(j.scale for j in self._joints)

    @property
    def report(self) -> Optional[ArmReport]:
        """Return the last cycle's report, None before the first cycle."""
        return self._report

    @property
    def frame_gap(self) -> float:
        """Return the time between two frames sent [s]."""
        return self._outbox.gap

    # --- commands (any thread) ---

    def set_velocity(self, qd: Sequence[float], now: Optional[float] = None) -> None:
        """
        Command joint velocities ``qd`` [rad/s], one per joint, each clipped to its max speed.

        InvalidInputError (code ``length``, ``non_finite``) on a wrong length or a non-finite
        value; the previous command stands. Kept on purpose although the driver node hands it
        velocities of a checked ``values.JogRequest``: a public call any script makes with raw
        numbers, and the last guard before the CAN set-points.
        """
        values = [float(v) for v in qd]
        if len(values) != len(self._joints):
            raise InvalidInputError(f'need {len(self._joints)} joint velocities, '
                                    f'got {len(values)}', 'length')
        if not all(v == v and abs(v) != float('inf') for v in values):
            raise NonFiniteError(f'joint velocities must be finite, got {values}')
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
            if joint == p.GRIPPER_JOINT:
                self.gripper.command_at(p.decode_gripper(bits), self.clock())

    def set_gripper(self, command: str) -> float:
        """
        Drive the gripper: 'open', 'closed' or 'off' (joint 4's outputs); return its arrival [s].

        The bits go with joint 4's next set-point; the gap is estimated (``gripper``).
        """
        with self._lock:
            j = self._joints[p.GRIPPER_JOINT - 1]
            j.outputs = p.encode_gripper(command, j.outputs)
            now = self.clock()
            self.gripper.command_at(command, now)
            return self.gripper.arrival(now)

    def request(self, kind: str, joints: Optional[Sequence[int]] = None,
                timeout: float = 2.0) -> Request:
        """
        Queue ``kind`` (reset, enable, disable, reference, set_zero) for ``joints`` (default all).

        Refused at once, with the reason, when it cannot be done safely (``driver_requests``);
        otherwise the control thread sends its frames from its next cycle on.
        """
        with self._lock:
            if self.listen_only:
                req = Request(kind, (), float(timeout))
                req.finish(False, f'{kind} refused: listen_only, the driver sends nothing')
                return req
            return self._requests.submit(kind, joints, timeout, self._moving())

    # --- the cycle ---

    def step(self, now: float) -> ArmReport:
        """Run one cycle at time ``now`` [s]: read replies, update, integrate, send."""
        with self._lock:
            dt = self.cycle if self._last_step is None else max(0.0, now - self._last_step)
            period = 0.0 if self._last_step is None else now - self._last_step
            self._last_step = now
            if self._link_up(now, period):
                if self.listen_only:
                    self._listen(now, period)
                else:
                    self._drive(now, dt, period)
        if self.on_cycle is not None:
            self.on_cycle(self._report)
        return self._report

    def _drive(self, now: float, dt: float, period: float) -> None:
        """One cycle that drives the arm (under the lock): read, decide, queue, send, answer."""
        if not self._started:
            self._started = True
            for n in range(1, len(self._joints) + 1):
                self._outbox.put(p.command_id(n), p.DISABLE, now)
        self._intake.read(self.bus, now, self.max_lag, self.cycle)
        self._requests.start(now)
        busy = self._requests.busy_joints()
        enabling = self._requests.enabling()
        hold = hold_reason(self._joints, busy, self.firmware, enabling)
        fresh = self._command is not None and now - self._command[1] <= self.command_timeout
        command = self._command[0] if fresh else [0.0] * len(self._joints)
        for n, (j, v) in enumerate(zip(self._joints, command), start=1):
            if n in busy or enabling:
                j.track = True               # the module moves itself: follow it
            integrate(j, v, dt, bool(hold), self.limit_set, self.max_lag)
        for n, j in enumerate(self._joints, start=1):
            self._queue_setpoint(n, j, now)
        self._requests.after_setpoints(now)
        self._outbox.send_due(now)
        for req in self._requests.check(now):
            if req.kind == 'enable' and req.ok:
                self._command = None         # motion starts from a command after enable
            hold = hold_reason(self._joints, self._requests.busy_joints(), self.firmware,
                               self._requests.enabling())
        self._report = self._make_report(now, hold, period)

    def _link_up(self, now: float, period: float) -> bool:
        """
        Tell whether the link to the adapter is up (under the lock); while it is lost, hold.

        A new loss forgets every position and answers every request; each cycle of the loss
        tries to reopen when due; a link back starts over as at start (disable to every module,
        the positions read again), not enabled until asked.
        """
        if self.link.lost(now):
            self._outbox.clear()
            self._requests.finish_all('refused: the link to the CAN adapter was lost')
            self._command = None
            for j in self._joints:
                j.forget()
        if self.link.lost_at is not None:
            if not self.link.poll(now):
                self._report = self._make_report(now, self.link.reason(now), period)
                return False
            self._started = False            # as at start: disable, then read every position
            self._intake.bus_error = self._outbox.error = ''    # the old link's errors
        return True

    def _listen(self, now: float, period: float) -> None:
        """One cycle of ``listen_only``: read and report, send nothing (under the lock)."""
        self._intake.read(self.bus, now, self.max_lag, self.cycle)
        for j in self._joints:
            j.setpoint = None if j.ticks is None else float(j.ticks)
        self._report = self._make_report(now, 'listen_only: the driver sends nothing', period)

    def _queue_setpoint(self, n: int, j: JointRecord, now: float) -> None:
        """Queue joint ``n``'s set-point at ``now`` [s], or, position unknown, a disable."""
        can_id = p.command_id(n)
        if j.ticks is None:
            self._outbox.put(can_id, p.DISABLE, now)
            if j.unknown_cycles >= PROBE_CYCLES:
                # A module that answers only set-points: poll it right behind the disable, so
                # it cannot act on the set-point; enable waits for one at its position.
                counter = j.next_counter()
                poll = p.encode_setpoint(j.scale.to_wire(0), counter, j.outputs)
                seq = self._outbox.put(can_id, poll, now)
                j.sent[counter] = (seq, 0)
            j.unknown_cycles += 1
            return
        ticks = round(j.setpoint) if j.setpoint is not None else j.ticks
        counter = j.next_counter()
        frame = p.encode_setpoint(j.scale.to_wire(ticks), counter, j.outputs)
        seq = self._outbox.put(can_id, frame, now)
        j.sent[counter] = (seq, ticks)

    def _moving(self) -> bool:
        command = self._command
        live = command is not None and self.clock() - command[1] <= self.command_timeout and \
            any(v != 0.0 for v in command[0])
        return live or any(j.velocity != 0.0 for j in self._joints)

    def _make_report(self, now: float, hold: str, period: float) -> ArmReport:
        joints = tuple(joint_report(j, self.firmware) for j in self._joints)
        state = arm_state(joints)
        intake, outbox = self._intake, self._outbox
        return ArmReport(time=now, state=state, hold=hold, joints=joints, period=period,
                         frames_dropped=int(getattr(self.bus, 'dropped', 0)),
                         frames_bad=intake.bad, tx_errors=outbox.tx_errors,
                         bus_error=outbox.error or intake.bus_error,
                         bad_frames=tuple(sorted(intake.bad_reasons.items())),
                         last_bad_frame=intake.last_bad,
                         link='lost' if self.link.lost_at is not None else 'up',
                         link_losses=self.link.losses, link_outage=self.link.last_outage,
                         gripper=self.gripper.report(now),
                         inputs=self._inputs())

    def _inputs(self) -> tuple[bool, ...]:
        """Return the digital inputs of joint 1's module's latest reply, () before one."""
        reply = self._joints[p.IO_JOINT - 1].reply
        return () if reply is None else p.decode_inputs(reply.inputs)

    # --- the control thread ---

    def send_due(self, now: float) -> None:
        """Send the queued frames that are due at ``now`` [s] (the control thread's job)."""
        with self._lock:
            self._outbox.send_due(now)

    def next_due(self) -> Optional[float]:
        """Return when the next queued frame is due [s], or None."""
        with self._lock:
            return self._outbox.next_due()

    def start(self) -> None:
        """Start the control thread: one ``step`` every ``cycle`` on ``clock``."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='mover6_driver', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as err:  # noqa: B902 - any death of the cycle is reported, not silent
            self.thread_error = f'{type(err).__name__}: {err}'
            self._report_death()

    def _report_death(self) -> None:
        """Hand over a last report: a fault that says the control thread died, and why."""
        hold = (f'control thread died ({self.thread_error}): nothing is sent any more, the '
                'modules stop on their watchdog; restart the driver')
        last = self._report
        if last is None:
            report = ArmReport(time=self.clock(), state=ModuleState.FAULT, hold=hold, joints=(),
                               period=0.0, frames_dropped=0, frames_bad=0, tx_errors=0,
                               bus_error=self.thread_error)
        else:
            report = replace(last, state=ModuleState.FAULT, hold=hold,
                             bus_error=self.thread_error)
        self._report = report
        if self.on_cycle is not None:
            try:
                self.on_cycle(report)
            except Exception:  # noqa: B902 - nothing more this thread can do
                pass

    @property
    def alive(self) -> bool:
        """Tell whether the control thread runs (False before ``start`` and after a death)."""
        return self._thread is not None and self._thread.is_alive()

    def _loop(self) -> None:
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
            self._outbox.clear()
            if not self.listen_only:
                for n in range(1, len(self._joints) + 1):
                    self._outbox.send_now(p.command_id(n), p.DISABLE)
            self._requests.finish_all('the driver shut down')
        self.bus.shutdown()
        if self.frame_log is not None:
            self.frame_log.stop()
