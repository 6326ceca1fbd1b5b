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
  at rest it is the whole tick sent, so a move of whole ticks lands on whole ticks;
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

The driver is five parts: this module (the commands, the cycle, the control thread),
``driver_state`` (each joint's record and state machine, the arm's state, the reports),
``setpoints`` (the set-point integrator), ``driver_replies`` (the bus intake) and
``driver_requests`` (reset, enable, disable, reference and set zero, and their confirmation).
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Optional, Sequence

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver_replies import DriverReplies
from mover6_control.hardware.driver_requests import DriverRequests
from mover6_control.hardware.driver_state import (
    arm_state, ArmReport, hold_reason, joint_report, JointRecord)
from mover6_control.hardware.scaling import JointScale
from mover6_control.hardware.setpoints import integrate
from mover6_control.realtime import run_at_priority


class ArmDriver(DriverReplies, DriverRequests):
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
        self._joints = [JointRecord(j) for j in joints]
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
            busy = self._busy_joints()
            hold = hold_reason(self._joints, busy, self.firmware)
            fresh = self._command is not None and now - self._command[1] <= self.command_timeout
            command = self._command[0] if fresh else [0.0] * len(self._joints)
            for n, (j, v) in enumerate(zip(self._joints, command), start=1):
                if n in busy:
                    j.track = True               # the module moves itself: follow it
                integrate(j, v, dt, bool(hold), self.limit_set, self.max_lag)
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

    def _make_report(self, now: float, hold: str, period: float) -> ArmReport:
        joints = tuple(joint_report(j, self.firmware) for j in self._joints)
        state = arm_state(joints)
        return ArmReport(time=now, state=state, hold=hold, joints=joints, period=period,
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
            self._finish_all('the driver shut down')
        self.bus.shutdown()
