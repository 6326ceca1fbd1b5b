"""
The Mover6 at CAN level: six simulated motor modules in front of the simulator's MuJoCo arm.

Frames in, frames out, as the real modules answer them (``mover6_control.hardware.protocol``
encodes and decodes every byte), and behind the modules the same ``Simulator`` and MuJoCo model
that ``sim_bridge`` runs, so one physics stands behind both simulations. ROS-free and
clock-free: the caller passes the receive time of every frame and the time to advance to (any
monotonic clock, in seconds); ``sim_bridge.can_sim`` puts the arm on a bus or a pseudo-terminal.

What a module does (the Mover6 modules' protocol version 1, as the vendor's driver ``cpr_robot``
uses it: ``MotorModule.cpp`` sends the frames and reads the replies, ``Joint.cpp`` converts
ticks and stops writing set-points while a module reports any error flag, ``CPRMover6.cpp``
gives gears, ticks and offsets; public copies in farshad-heravi/cpr_robot and
jonaitken/cpr_ros2; and the Mover6 user guide's CAN pages):

- It takes frames on ``joint << 4`` and answers on that ID + 1. A frame of any other length
  than its command's (a set-point has 8 bytes, set zero 4, the other commands 2) or with an
  unknown payload is ignored, and counted in ``ignored``.
- It answers every position set-point at once with its error flags, its encoder position (ticks
  plus the joint's offset, int32 big-endian), the set-point's counter byte as its timestamp (the
  user guide: the module copies the command's timestamp into its answer) and its inputs (0x80 once
  referenced). With ``answers_commands`` (a module answers every command it takes) it answers
  reset, enable, disable, referencing and set zero too, with timestamp 0 (those frames carry
  none); without it only set-points are answered, the worst a driver may meet.
- Error flags: 0x1C after power-up (motor not enabled, communication watchdog, position lag),
  0x04 after a reset, 0x00 after an enable. Enable is taken only when nothing but 0x04 is set
  (after a reset); otherwise it changes nothing. Any error flag stops the motor and sets 0x04.
- Motion: while enabled the motor follows its set-points, each interpolated linearly over the
  interval between the last two set-points (the driver's cycle), at most at the joint's speed
  limit. A disabled module keeps the last set-point it was sent, and **enabling drives there**
  at the joint's top speed (the worst a firmware may do: the reason the vendor's enable first
  sets the set-point to the measured position); with no set-point yet it holds where it is.
  When the reference runs more than ``lag_limit`` ahead of the position, the module raises
  position lag (0x10). ``max_setpoint_gap`` keeps the largest distance between a set-point an
  enabled module was sent (or kept, at enable) and its position then [wire ticks]: what a test
  reads to see a jump; ``setpoint_range`` the lowest and highest set-point taken.
- Communication watchdog: an enabled module that gets no set-point for ``watchdog_timeout``
  raises 0x08 and stops.
- Start referencing and set zero take effect on the second of two commands; set zero's second
  must follow within ``set_zero_window`` (0.5 s), referencing's within ``reference_window``.
  Referencing needs the motor enabled: the motor drives from where it is to its reference
  switch at ``reference_speed``, stays ``reference_time`` there, then sets the referenced bit
  (set-points that come meanwhile are kept, not followed). The switch is at the joint's zero
  (the simulated encoder already counts from the true zero). A brown-out restarts the module:
  the referenced bit drops. Set zero makes the
  present position read the value in its last two bytes on the wire (big-endian, as
  ``protocol.encode_set_zero`` sends it; the vendor's driver always sends 0).

What is this simulation's and not the vendor's (no vendor source gives the firmware's numbers;
they are parameters, to be checked on the real arm): ``watchdog_timeout``, ``lag_limit``,
``reference_time``, ``reference_window``, ``reference_speed`` and the switch at the joint's zero
(no vendor source read here gives the referencing speed or the switches' angles), the
interpolation of set-points, that the watchdog,
the position lag and an injected flag also set 0x04, what a reply to a command carries, and the
drive to a kept set-point on enable.

The gripper (``SimGripper``): joint 4's module drives it by its output bits (bit 1 enabled, bit 0
open: ``protocol.decode_gripper``), taken with every set-point; its gap runs between 0 and
``GRIPPER_STROKE`` in ``GRIPPER_TIME`` (this simulation's numbers: no vendor source gives them),
and it reports nothing back, as the real one. The arm's digital inputs are joint 1's module's
``inputs`` (``set_inputs``), reported in every reply's ``data[7]`` beside the referenced bit.

Faults to inject (``inject_flags``, ``set_silent``): any error flags on a module (cleared by a
reset unless sticky), and a silent module that takes commands but never answers. A corrupted
byte on the wire belongs to the serial adapter: ``sim_bridge.can_sim`` injects it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
import math

from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol
from mover6_control.hardware.protocol import NOT_ENABLED
from mover6_control.hardware.scaling import JointScale
from mover6_control.kinematics.arm import ArmModel
import numpy as np
from sim_bridge.pacing import steps_due
from sim_bridge.simulator import SimConfig, Simulator

BROWN_OUT = 0x01
WATCHDOG = 0x08
POSITION_LAG = 0x10
POWER_UP_FLAGS = NOT_ENABLED | WATCHDOG | POSITION_LAG      # 0x1C

_MIN_INTERVAL = 0.005        # [s] the shortest interval a set-point is interpolated over
_MAX_INTERVAL = 0.2          # [s] the longest
_MAX_STEPS = 500             # physics steps per advance() before the arm gives up catching up
FRAMES_KEPT = 4096           # frames each module keeps for ``take_frames`` (the oldest go)


@dataclass(frozen=True)
class ModuleTiming:
    """The modules' firmware numbers this simulation assumes; units in brackets."""

    watchdog_timeout: float = 0.5      # [s] without a set-point, while enabled (10 cycles)
    lag_limit: float = 0.1             # [rad] reference ahead of position before 0x10
    set_zero_window: float = 0.5       # [s] the second set zero within this
    reference_window: float = 1.0      # [s] the second start referencing within this
    reference_time: float = 0.5        # [s] at the switch before the referenced bit
    reference_speed: float = 0.2       # [rad/s] joint speed while driving to the switch
    gain: float = 50.0                 # [1/s] the module's position loop

    def __post_init__(self):
        """Check that every number is positive and finite."""
        for name in ('watchdog_timeout', 'lag_limit', 'set_zero_window', 'reference_window',
                     'reference_time', 'reference_speed', 'gain'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidInputError(f'{name} must be positive and finite, got {value}')


GRIPPER_STROKE = 0.03        # [m] the simulated gripper's gap when open
GRIPPER_TIME = 0.8           # [s] the simulated gripper from closed to open


class SimGripper:
    """The gripper on joint 4's outputs: its gap [m] follows the command bits over time."""

    def __init__(self, stroke: float = GRIPPER_STROKE, stroke_time: float = GRIPPER_TIME) -> None:
        """Start closed, not driven."""
        self.stroke = float(stroke)
        self.speed = self.stroke / float(stroke_time)
        self.gap = 0.0
        self.command = 'off'
        self._time = None

    def advance(self, outputs: int, now: float) -> None:
        """Move the gap to ``now`` [s] under the output bits ``outputs`` (joint 4's module)."""
        dt = 0.0 if self._time is None else max(0.0, now - self._time)
        self._time = now
        self.command = protocol.decode_gripper(outputs)
        goal = {'open': self.stroke, 'closed': 0.0}.get(self.command)
        if goal is None:
            return
        step = self.speed * dt
        self.gap = goal if abs(goal - self.gap) <= step else \
            self.gap + step * (1.0 if goal > self.gap else -1.0)


class MotorModule:
    """
    The state of one simulated motor module: flags, enable, set-points, referencing, faults.

    It never touches the physics: ``CanArm`` reads its reference and reports the encoder.
    Positions here are on the wire's scale [ticks, offset included]; ``ref_time`` etc. [s].
    """

    def __init__(self, joint: int, timing: ModuleTiming, top_speed: float = 1.0e4,
                 answers_commands: bool = True, switch: float = 0.0,
                 reference_speed: float = 1.0e3) -> None:
        """
        Power the module up: flags 0x1C, motor off, not referenced.

        ``top_speed`` [wire ticks/s] is how fast it drives to a kept set-point on enable;
        ``answers_commands``: it answers commands as well as set-points. ``switch`` [wire
        ticks, before set zero] is where referencing drives to, at ``reference_speed``
        [wire ticks/s].
        """
        self.joint = joint
        self.timing = timing
        self.top_speed = float(top_speed)
        self.answers_commands = bool(answers_commands)
        self.switch = float(switch)
        self.reference_speed = float(reference_speed)
        self.max_setpoint_gap = 0      # [wire ticks] the largest set-point an enabled one met
        self.setpoint_range = None     # (lowest, highest) set-point taken [wire ticks]
        self.flags = POWER_UP_FLAGS
        self.enabled = False
        self.referenced = False
        self.silent = False
        self.sticky_flags = 0          # injected flags that a reset does not clear
        self.timestamp = 0
        self.digital_out = 0
        self.inputs = 0                # digital inputs besides the referenced bit
        self.bias = 0                  # [ticks] set zero moves the module's zero by this
        self.ignored = 0               # frames of a wrong length or unknown payload
        self.setpoints = 0             # set-points taken
        self.replies = 0               # replies sent
        self.last_setpoint = None      # the last set-point [wire ticks], or None
        self.setpoint_changed = None   # when a set-point last differed from the one before [s]
        self._setpoint_time = None     # when it came [s]
        self._interval = 0.05          # [s] between the last two set-points
        self._ref_from = 0.0           # the reference ramps from this [wire ticks] ...
        self._ref_to = 0.0             # ... to this ...
        self._ramp_start = 0.0         # ... from this time [s] ...
        self._ramp_time = _MIN_INTERVAL  # ... over this long [s]
        self._armed = {}               # kind -> time of the first of a two-command pair
        self._referencing_until = None
        self._taken = deque(maxlen=FRAMES_KEPT)   # (time, kind, wire ticks or None)
        self._taken_lost = 0           # frames that fell out of ``_taken`` unread

    # --- the wire ------------------------------------------------------------------------

    def receive(self, data: bytes, now: float, encoder: int) -> bytes | None:
        """
        Take one frame's payload at ``now`` [s]; return the reply payload or None.

        ``encoder`` [ticks, offset included] is the motor's count now; the module reports it
        moved by its zero (``bias``). A silent module still acts on the frame.
        """
        position = encoder + self.bias
        try:
            command = protocol.decode_command(data)
        except protocol.ProtocolError:
            self.ignored += 1
            return None
        if len(self._taken) == FRAMES_KEPT:
            self._taken_lost += 1
        self._taken.append((now, command.kind,
                            command.position if command.kind == 'setpoint' else None))
        if command.kind == 'setpoint':
            self._take_setpoint(command, now, position)
        elif command.kind == 'reset':
            self.flags = NOT_ENABLED | self.sticky_flags
            self.enabled = False
            self._armed.clear()
            self._referencing_until = None
        elif command.kind == 'enable':
            if self.flags & ~NOT_ENABLED == 0 and not self.enabled:
                self.enabled = True
                self.flags = 0
                self._drive_to_kept(position, now)
        elif command.kind == 'disable':
            self._stop(position, now)
        elif command.kind == 'reference':
            if self._second_of_pair('reference', now, self.timing.reference_window) \
                    and self.enabled:
                self._start_referencing(position, now)
        elif command.kind == 'set_zero':
            if self._second_of_pair('set_zero', now, self.timing.set_zero_window):
                self.bias += command.position - position
                position = command.position
                self._hold(position, now)
        if self.silent or (command.kind != 'setpoint' and not self.answers_commands):
            return None
        self.timestamp = command.counter if command.kind == 'setpoint' else 0
        return self._reply(position)

    def _drive_to_kept(self, position, now):
        """On enable: drive from ``position`` to the kept set-point at top speed, if any."""
        kept = self.last_setpoint
        if kept is None:
            self._hold(position, now)
            return
        self.max_setpoint_gap = max(self.max_setpoint_gap, abs(kept - position))
        self._ref_from, self._ref_to = float(position), float(kept)
        self._ramp_start = now
        self._ramp_time = max(abs(kept - position) / self.top_speed, _MIN_INTERVAL)

    def _start_referencing(self, position, now):
        """Drive from ``position`` [wire ticks] to the switch at the referencing speed."""
        target = self.switch + self.bias
        self._ref_from, self._ref_to = float(position), target
        self._ramp_start = now
        self._ramp_time = max(abs(target - position) / self.reference_speed, _MIN_INTERVAL)
        self._referencing_until = now + self._ramp_time + self.timing.reference_time

    def _reply(self, position):
        """Return the reply payload for the encoder at ``position`` [wire ticks]."""
        self.replies += 1
        inputs = (self.inputs & ~protocol.REFERENCED) | \
            (protocol.REFERENCED if self.referenced else 0)
        return protocol.encode_reply(self.flags, int(position), self.timestamp, inputs)

    def _second_of_pair(self, kind, now, window):
        """Return True when this command is the second of its pair within ``window`` [s]."""
        first = self._armed.pop(kind, None)
        if first is not None and now - first <= window:
            return True
        self._armed[kind] = now
        return False

    def _take_setpoint(self, command, now, position):
        """Store a set-point and start the reference's ramp to it."""
        self.setpoints += 1
        lo, hi = self.setpoint_range or (command.position, command.position)
        self.setpoint_range = (min(lo, command.position), max(hi, command.position))
        if self.enabled:
            self.max_setpoint_gap = max(self.max_setpoint_gap,
                                        abs(command.position - position))
        self.digital_out = command.digital_out
        if self._setpoint_time is not None:
            self._interval = min(max(now - self._setpoint_time, _MIN_INTERVAL), _MAX_INTERVAL)
        self._setpoint_time = now
        if command.position != self.last_setpoint:
            self.setpoint_changed = now
        self.last_setpoint = command.position
        if self.enabled and self._referencing_until is None:
            self._ref_from = self.reference(now)
            self._ref_to = float(command.position)
            self._ramp_start = now
            self._ramp_time = self._interval

    def _hold(self, position, now):
        """Make ``position`` [wire ticks] the reference, still."""
        self._ref_from = self._ref_to = float(position)
        self._ramp_start = now

    def _stop(self, position, now):
        """Stop the motor where it is; the flags say 0x04."""
        self.enabled = False
        self.flags |= NOT_ENABLED
        self._referencing_until = None
        self._hold(position, now)

    def reference(self, now: float) -> float:
        """Return where the motor is asked to be at ``now`` [wire ticks]."""
        ramp = (now - self._ramp_start) / self._ramp_time
        if ramp >= 1.0:
            return self._ref_to
        return self._ref_from + (self._ref_to - self._ref_from) * max(ramp, 0.0)

    def reference_rate(self, now: float) -> float:
        """Return the reference's rate at ``now`` [wire ticks/s] (0 once it arrived)."""
        if self.enabled and 0.0 <= now - self._ramp_start < self._ramp_time:
            return (self._ref_to - self._ref_from) / self._ramp_time
        return 0.0

    # --- time ----------------------------------------------------------------------------

    def supervise(self, now: float, encoder: int, lag_ticks: float) -> None:
        """Run the lag check and referencing at ``now`` [s]."""
        position = encoder + self.bias
        if self._referencing_until is not None and now >= self._referencing_until:
            self._referencing_until = None
            self.referenced = True
        if self.enabled and abs(self.reference(now) - position) > lag_ticks:
            self.flags |= POSITION_LAG
            self._stop(position, now)

    def watchdog(self, now: float, encoder: int) -> None:
        """Trip the communication watchdog if no set-point came for its timeout at ``now``."""
        if self.enabled and (self._setpoint_time is None or now - self._setpoint_time >
                             self.timing.watchdog_timeout):
            self.flags |= WATCHDOG
            self._stop(encoder + self.bias, now)

    def inject(self, flags: int, encoder: int, now: float, sticky: bool = False) -> None:
        """Raise error ``flags`` (0..255) at ``now`` [s]; any error stops the motor."""
        self.flags |= flags
        if flags & BROWN_OUT:
            self.referenced = False      # the module restarted: its reference is gone
        if sticky:
            self.sticky_flags |= flags
        self._stop(encoder + self.bias, now)

    def take_frames(self) -> dict:
        """
        Return the frames taken since the last call, and forget them.

        ``frames``: ``[time [s], kind, wire ticks]`` in order (kind as ``protocol.decode_command``
        names it; ticks only for a set-point, else None), at most ``FRAMES_KEPT``; ``lost``: how
        many older ones fell out unread.
        """
        frames = [list(f) for f in self._taken]
        lost, self._taken_lost = self._taken_lost, 0
        self._taken.clear()
        return {'frames': frames, 'lost': lost}

    def status(self) -> dict:
        """Return the module's state as plain values."""
        return {'flags': self.flags, 'enabled': self.enabled, 'referenced': self.referenced,
                'referencing': self._referencing_until is not None,
                'silent': self.silent, 'setpoint': self.last_setpoint, 'bias': self.bias,
                'setpoints': self.setpoints, 'setpoint_changed': self.setpoint_changed,
                'replies': self.replies, 'ignored': self.ignored,
                'digital_out': self.digital_out, 'max_setpoint_gap': self.max_setpoint_gap,
                'setpoint_range': self.setpoint_range}


class CanArm:
    """
    Six motor modules on one CAN bus, moving one simulated arm.

    ``receive`` takes a frame and returns the replies; ``advance`` runs the physics and the
    modules' supervision up to a time. Both take times on the caller's monotonic clock [s];
    the physics runs at real time from the first call. Not thread-safe.
    """

    def __init__(self, arm: ArmModel, scales: Sequence[JointScale],
                 timing: ModuleTiming | None = None, home_q: np.ndarray | None = None,
                 sim_config: SimConfig | None = None, answers_commands: bool = True) -> None:
        """
        Power up at rest at ``home_q`` (n,) [rad] (zeros): every module reports 0x1C.

        ``scales`` are the joints' scaling as the driver reads it (``hardware.scaling``, from
        config/mover6_joints.yaml): the modules count with the driver's gears, ticks and
        offsets, so the simulation cannot check them (J1's sign least of all).
        ``answers_commands``: the modules answer commands too, not only set-points.
        """
        if len(scales) != arm.n_joints or arm.n_joints != len(protocol.JOINTS):
            raise InvalidInputError(
                f'a Mover6 has {len(protocol.JOINTS)} modules: got {len(scales)} scales for '
                f'{arm.n_joints} joints')
        self.arm = arm
        self.scales = tuple(scales)
        self.timing = timing or ModuleTiming()
        self.sim = Simulator(arm, sim_config or SimConfig(mode='rad_per_s'), home_q)
        self._tpr = np.array([s.ticks_per_rad for s in self.scales])
        self.modules = tuple(
            MotorModule(j, self.timing, abs(v * t), answers_commands, switch=s.offset,
                        reference_speed=abs(self.timing.reference_speed * t))
            for j, v, t, s in zip(protocol.JOINTS, arm.velocity_limits, self._tpr,
                                  self.scales))
        self._offset = np.array([s.offset for s in self.scales], dtype=float)
        self._lag_ticks = np.abs(self.timing.lag_limit * self._tpr)
        self._vmax = np.array(arm.velocity_limits)
        self._names = list(arm.joint_names)
        self._t0 = None                            # caller time at sim time _sim0
        self._sim0 = self.sim.time
        self.frames_in = 0
        self.foreign = 0                           # frames on IDs no module takes
        self.gripper = SimGripper()

    # --- the encoders --------------------------------------------------------------------

    def encoders(self) -> np.ndarray:
        """Return every motor's count now (6,) [ticks, offset included, before set zero]."""
        return np.round(self.sim.q * self._tpr + self._offset).astype(np.int64)

    def positions(self) -> np.ndarray:
        """Return what every module reports now (6,) [wire ticks]."""
        return self.encoders() + np.array([m.bias for m in self.modules], dtype=np.int64)

    def ticks_of(self, q: np.ndarray) -> np.ndarray:
        """Return what the modules would report at joint positions ``q`` (6,) [rad]."""
        bias = np.array([m.bias for m in self.modules], dtype=float)
        return np.round(np.asarray(q, dtype=float) * self._tpr + self._offset + bias).astype(
            np.int64)

    # --- frames --------------------------------------------------------------------------

    def receive(self, can_id: int, data: bytes, now: float) -> list[tuple[int, bytes]]:
        """Take one frame at ``now`` [s]; return the replies as (CAN ID, payload)."""
        self._run_physics(now)
        self.gripper.advance(self.modules[protocol.GRIPPER_JOINT - 1].digital_out, now)
        self.frames_in += 1
        try:
            joint, is_reply = protocol.joint_of_id(can_id)
        except protocol.ProtocolError:
            self.foreign += 1
            return []
        if is_reply:
            self.foreign += 1
            return []
        i = joint - 1
        module = self.modules[i]
        reply = module.receive(bytes(data), now, int(self.encoders()[i]))
        if reply is None:
            return []
        return [(protocol.reply_id(joint), reply)]

    # --- physics -------------------------------------------------------------------------

    def advance(self, now: float) -> int:
        """
        Run the physics and the modules up to ``now`` [s]; return the physics steps run.

        The communication watchdog is checked at ``now`` only, after the physics: a caller that
        was itself held up (a loaded machine) first takes every frame that arrived meanwhile
        (``receive`` with the time it reads them), so a late simulator never trips the watchdog
        of a driver that sent in time.
        """
        n = self._run_physics(now)
        encoders = self.encoders()
        for i, module in enumerate(self.modules):
            module.watchdog(now, int(encoders[i]))
        self.gripper.advance(self.modules[protocol.GRIPPER_JOINT - 1].digital_out, now)
        return n

    def _run_physics(self, now):
        """Step the physics up to ``now`` [s], supervising lag at every step; return the steps."""
        if self._t0 is None:
            self._t0 = now
        dt = self.sim.config.physics_dt
        n = steps_due(self.sim.time - self._sim0, now - self._t0, 1.0, dt, _MAX_STEPS)
        if n >= _MAX_STEPS:                       # fell behind: carry on from here
            self._t0, self._sim0 = now, self.sim.time + n * dt
        t_first = now - (n - 1) * dt if n else now
        for k in range(n):
            self._step(t_first + k * dt)
        if n == 0:
            self._supervise(now)
        return n

    def _step(self, t):
        """One physics step at caller time ``t`` [s]: supervise, then drive each motor."""
        self._supervise(t)
        q = self.sim.q
        v = np.zeros(len(self.modules))
        for i, module in enumerate(self.modules):
            if module.enabled:
                ref = (module.reference(t) - module.bias - self._offset[i]) / self._tpr[i]
                ff = module.reference_rate(t) / self._tpr[i]
                v[i] = ff + self.timing.gain * (ref - q[i])
        v = np.clip(v, -self._vmax, self._vmax)
        self.sim.set_command(self._names, v, self.sim.time)
        self.sim.step(1)

    def _supervise(self, t):
        """Run every module's lag check and referencing at ``t`` [s]."""
        encoders = self.encoders()
        for i, module in enumerate(self.modules):
            module.supervise(t, int(encoders[i]), self._lag_ticks[i])

    # --- faults and state ----------------------------------------------------------------

    def inject_flags(self, joint: int, flags: int, now: float, sticky: bool = False) -> None:
        """Raise error ``flags`` on the module of ``joint`` (1..6) at ``now`` [s]."""
        module = self._module(joint)
        if isinstance(flags, bool) or not isinstance(flags, int) or not 0 < flags <= 0xFF:
            raise InvalidInputError(f'flags must be an int in 1..255, got {flags!r}')
        self.advance(now)
        module.inject(flags, int(self.encoders()[joint - 1]), now, sticky)

    def set_inputs(self, bits: int) -> None:
        """Set the arm's digital inputs (joint 1's module, bits 0..6; 0x80 is not an input)."""
        if isinstance(bits, bool) or not isinstance(bits, int) or not 0 <= bits <= 0x7F:
            raise InvalidInputError(f'inputs must be an int in 0..0x7F, got {bits!r}')
        self.modules[protocol.IO_JOINT - 1].inputs = bits

    def set_silent(self, joint: int, silent: bool) -> None:
        """Make the module of ``joint`` (1..6) stop answering (True) or answer again."""
        self._module(joint).silent = bool(silent)

    def take_frames(self) -> list[dict]:
        """Return every module's frames since the last call (``MotorModule.take_frames``)."""
        return [m.take_frames() for m in self.modules]

    def _module(self, joint):
        """Return the module of ``joint`` or raise."""
        if isinstance(joint, bool) or not isinstance(joint, int) or joint not in protocol.JOINTS:
            raise InvalidInputError(f'joint must be one of {protocol.JOINTS}, got {joint!r}')
        return self.modules[joint - 1]

    def status(self) -> dict:
        """Return the arm's state as plain values: q [rad], encoders, every module."""
        return {'time': self.sim.time, 'q': self.sim.q.tolist(),
                'positions': self.positions().tolist(), 'frames_in': self.frames_in,
                'foreign': self.foreign, 'modules': [m.status() for m in self.modules],
                'gripper': {'gap': self.gripper.gap, 'command': self.gripper.command}}
