"""
The Mover6 motor modules' CAN protocol as pure functions: frame IDs, command and reply codecs.

No I/O here: bytes in, values out, and back. The facts, checked against the vendor's sources:

- IDs (11-bit, CAN 2.0A, 500 kbit/s): module n (joint n, 1..6) takes commands on ``n << 4`` and
  answers on ``(n << 4) + 1``; the vendor creates joint i with module ID i + 1 (``Robot.cpp``) and
  addresses ``moduleId << 4`` / ``(moduleId << 4) + 1`` (``MotorModule.cpp``).
- Position set-point, DLC 8: ``[0x14, 0x00, p >> 24, p >> 16, p >> 8, p, counter, digital_out]``
  with ``p`` the int32 ticks plus the joint's offset, the counter one byte that wraps
  (``MotorModule::Command_SetJoint``).
- Commands (``MotorModule::Command_*``): reset errors ``[0x01, 0x06]``, enable ``[0x01, 0x09]``,
  disable ``[0x01, 0x0A]``, start referencing ``[0x01, 0x0B]``, all DLC 2; set zero
  ``[0x01, 0x08, v1, v0]``, DLC 4, whose last two bytes carry the new zero value (the user
  guide's example ``0x01 0x08 0x7D 0x00``; assumed big-endian and unsigned like every other value
  on this bus: ``encode_set_zero``; the vendor always sends 0). The vendor sends enable,
  referencing and set-zero twice, 20 ms apart (``MotorModule::Enable``, ``StartReferencing``,
  ``SetZero``); that timing belongs to the driver, not here.
- Reply, DLC 8: ``data[0]`` error flags, ``data[1..4]`` position int32 big-endian (minus the offset
  gives ticks), ``data[5]`` a timestamp, which the user guide says the module copies from the
  command it answers (a set-point's counter byte; the vendor's ``Joint.cpp`` ignores a reply
  whose timestamp did not change), ``data[7]`` digital inputs, bit 0x80 "referenced"
  (``MotorModule::get_CurrentPosition``, ``Joint::DATABIT_REFERENCED``). ``data[6]`` is not read
  by the vendor; it is kept in ``Reply.spare``.
- Digital outputs and inputs (``CPRMover6.cpp``'s ``define_Output`` / ``define_Input``,
  ``Joint::set_DigitalOutput`` / ``get_DigitalInput``, ``Robot::PublishState``): each module
  sends its output bits in a set-point's last byte and reports its input bits in a reply's
  ``data[7]`` (bit ``n`` is channel ``n``). The Mover6's gripper is on joint 4's module
  (``moduleIndex`` 3): bit 0 "Gripper open", bit 1 "Gripper enabled"; joint 1's module carries
  "Digital out 1..4" (bits 0..3) and "Digital in 1..3" (bits 0..2), which the vendor publishes
  on ``/InputChannels``. The gripper reports nothing back: no position, no force.
- Error flags of the Mover6 modules, as the Mover6 user guide's CAN pages name them: 0x01
  brown-out, 0x02 velocity lag, 0x04 motor not enabled, 0x08 communication watchdog, 0x10 position
  lag, 0x20 encoder, 0x40 over-current, 0x80 CAN. The newer CAN V2 modules reuse 0x04..0x20 but
  give 0x01 over-temperature, 0x02 e-stop / supply too low, 0x40 driver error, 0x80 over-current
  (the vendor's iRC ROS hardware interface, ``ErrorState`` of its CPRCANv2 driver).

Sources (read, not copied): the vendor's ROS 1 driver ``cpr_robot`` in its public fork
farshad-heravi/cpr_robot (``src/MotorModule.cpp``, ``src/Joint.cpp``, ``src/Robot.cpp``), its ROS 2
port jonaitken/cpr_ros2 (``src/MotorModule.cpp``, ``src/CPRMover6.cpp``, ``src/Robot.cpp``,
``include/cpr_robot/Joint.h``), and the Mover6 user guide (2014), CAN protocol pages.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from mover6_control.errors import Mover6Error

BITRATE = 500000
"""The bit rate of the Mover6's CAN bus [bit/s]."""

JOINTS = (1, 2, 3, 4, 5, 6)
"""The module numbers of the six joints; joint n is module n."""

SETPOINT_HEADER = b'\x14\x00'
RESET_ERRORS = b'\x01\x06'
ENABLE = b'\x01\x09'
DISABLE = b'\x01\x0a'
START_REFERENCING = b'\x01\x0b'
SET_ZERO_HEADER = b'\x01\x08'
SET_ZERO = SET_ZERO_HEADER + b'\x00\x00'

GRIPPER_JOINT = 4
"""The module whose digital outputs drive the gripper (the vendor's joint index 3)."""
GRIPPER_OPEN = 0x01
"""Joint 4's output bit "Gripper open" (set: open, clear: closed, while enabled)."""
GRIPPER_ENABLED = 0x02
"""Joint 4's output bit "Gripper enabled" (clear: the gripper is not driven)."""
GRIPPER_COMMANDS = ('off', 'open', 'closed')
IO_JOINT = 1
"""The module carrying the arm's digital outputs 1..4 and inputs 1..3."""
INPUT_CHANNELS = ('Digital in 1', 'Digital in 2', 'Digital in 3')
OUTPUT_CHANNELS = ('Digital out 1', 'Digital out 2', 'Digital out 3', 'Digital out 4')

REFERENCED = 0x80
"""The bit of a reply's inputs byte that tells the joint is referenced."""
NOT_ENABLED = 0x04
"""The error flag "motor not enabled", the same in every firmware's table."""

# The fixed commands by their payload (exact length included: a module ignores any other).
_COMMANDS = {
    RESET_ERRORS: 'reset',
    ENABLE: 'enable',
    DISABLE: 'disable',
    START_REFERENCING: 'reference',
    SET_ZERO: 'set_zero',
}

COMMAND_KINDS = ('setpoint', 'reset', 'enable', 'disable', 'reference', 'set_zero')
COMMAND_FRAMES = {kind: data for data, kind in _COMMANDS.items()}
"""The payload of each fixed command by its kind (every kind but 'setpoint')."""

ERROR_FLAGS = {
    'mover6': {
        0x01: 'brown_out',
        0x02: 'velocity_lag',
        0x04: 'motor_not_enabled',
        0x08: 'comm_watchdog',
        0x10: 'position_lag',
        0x20: 'encoder',
        0x40: 'over_current',
        0x80: 'can',
    },
    'can_v2': {
        0x01: 'over_temperature',
        0x02: 'estop_or_low_supply',
        0x04: 'motor_not_enabled',
        0x08: 'comm_watchdog',
        0x10: 'position_lag',
        0x20: 'encoder',
        0x40: 'driver',
        0x80: 'over_current',
    },
}
"""Name of each error-flag bit of a reply, per module firmware; 'mover6' is the default."""

INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1


class ProtocolError(Mover6Error, ValueError):
    """A frame or a value that the protocol has no meaning for (wrong length, unknown, range)."""


@dataclass(frozen=True)
class Command:
    """
    A decoded command frame: ``kind`` is one of ``COMMAND_KINDS``.

    ``position`` [ticks, offset included, as on the wire], ``counter`` and ``digital_out`` are set
    for a 'setpoint' and None for every other kind, except set zero's ``position``: the value the
    module is to read at its present position (``encode_set_zero``).
    """

    kind: str
    position: Optional[int] = None
    counter: Optional[int] = None
    digital_out: Optional[int] = None


@dataclass(frozen=True)
class Reply:
    """A decoded reply frame; ``position`` [ticks, offset included, as on the wire]."""

    error_flags: int
    position: int
    timestamp: int
    inputs: int
    spare: int = 0

    @property
    def referenced(self) -> bool:
        """Tell whether the module reports its joint as referenced: bit 0x80 of the inputs."""
        return bool(self.inputs & REFERENCED)


def _check_joint(joint: int) -> int:
    if isinstance(joint, bool) or not isinstance(joint, int) or joint not in JOINTS:
        raise ProtocolError(f'joint must be one of {JOINTS}, got {joint!r}')
    return joint


def _check_byte(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFF:
        raise ProtocolError(f'{name} must be an int in 0..255, got {value!r}')
    return value


def _check_int32(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or \
            not INT32_MIN <= value <= INT32_MAX:
        raise ProtocolError(f'{name} must be an int32, got {value!r}')
    return value


def command_id(joint: int) -> int:
    """Return the CAN ID on which the module of ``joint`` (1..6) takes commands: joint << 4."""
    return _check_joint(joint) << 4


def reply_id(joint: int) -> int:
    """Return the CAN ID on which the module of ``joint`` (1..6) answers: command ID + 1."""
    return command_id(joint) + 1


def joint_of_id(can_id: int) -> tuple[int, bool]:
    """Return ``(joint, is_reply)`` of a Mover6 CAN ID; ProtocolError for any other ID."""
    if isinstance(can_id, int) and not isinstance(can_id, bool) and \
            (can_id & 0x0F) in (0, 1) and (can_id >> 4) in JOINTS:
        return can_id >> 4, bool(can_id & 0x01)
    raise ProtocolError(f'CAN ID {can_id!r} is no Mover6 module command or reply ID')


def encode_setpoint(position: int, counter: int, digital_out: int = 0) -> bytes:
    """
    Return the 8 bytes of a position set-point.

    ``position`` [ticks, offset included] is an int32 sent big-endian; only the low byte of
    ``counter`` is sent (it wraps); ``digital_out`` is the module's output bits (0..255).
    """
    _check_int32(position, 'position')
    if isinstance(counter, bool) or not isinstance(counter, int):
        raise ProtocolError(f'counter must be an int, got {counter!r}')
    _check_byte(digital_out, 'digital_out')
    return SETPOINT_HEADER + position.to_bytes(4, 'big', signed=True) + \
        bytes((counter & 0xFF, digital_out))


def encode_set_zero(value: int) -> bytes:
    """
    Return the 4 bytes of set zero: the module is to read ``value`` (0..65535) where it is now.

    ``value`` [ticks, offset included, as on the wire] goes big-endian in the last two bytes; the
    joint reads angle 0 afterwards when ``value`` is its offset (500 for J5, 509 for J6).
    """
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
        raise ProtocolError(f'set zero value must be an int in 0..65535, got {value!r}')
    return SET_ZERO_HEADER + value.to_bytes(2, 'big')


def decode_command(data: bytes) -> Command:
    """Return the command of a frame's payload; ProtocolError on a wrong length or unknown."""
    data = bytes(data)
    if data[:2] == SETPOINT_HEADER:
        if len(data) != 8:
            raise ProtocolError(f'a set-point has 8 bytes, got {len(data)}: {data.hex()}')
        return Command('setpoint', int.from_bytes(data[2:6], 'big', signed=True), data[6],
                       data[7])
    if data[:2] == SET_ZERO_HEADER and len(data) == 4:
        return Command('set_zero', int.from_bytes(data[2:4], 'big'))
    kind = _COMMANDS.get(data)
    if kind is None:
        raise ProtocolError(f'unknown command or wrong length ({len(data)} bytes): {data.hex()}')
    return Command(kind)


def encode_reply(error_flags: int, position: int, timestamp: int, inputs: int,
                 spare: int = 0) -> bytes:
    """Return the 8 bytes of a module's reply; ``position`` [ticks, offset included]."""
    _check_byte(error_flags, 'error_flags')
    _check_int32(position, 'position')
    _check_byte(timestamp, 'timestamp')
    _check_byte(inputs, 'inputs')
    _check_byte(spare, 'spare')
    return bytes((error_flags,)) + position.to_bytes(4, 'big', signed=True) + \
        bytes((timestamp, spare, inputs))


def decode_reply(data: bytes) -> Reply:
    """Return the reply of a frame's payload; ProtocolError unless it has 8 bytes."""
    data = bytes(data)
    if len(data) != 8:
        raise ProtocolError(f'a reply has 8 bytes, got {len(data)}: {data.hex()}')
    return Reply(data[0], int.from_bytes(data[1:5], 'big', signed=True), data[5], data[7],
                 data[6])


def flag_names(flags: int, firmware: str = 'mover6') -> tuple[str, ...]:
    """Return the names of the bits set in ``flags``, lowest bit first, per ``firmware``."""
    table = ERROR_FLAGS.get(firmware)
    if table is None:
        raise ProtocolError(f'firmware must be one of {sorted(ERROR_FLAGS)}, got {firmware!r}')
    _check_byte(flags, 'flags')
    return tuple(name for bit, name in sorted(table.items()) if flags & bit)


def encode_gripper(command: str, outputs: int = 0) -> int:
    """
    Return joint 4's output bits ``outputs`` (0..255) with the gripper's two set for ``command``.

    ``command``: 'off' (not driven), 'open' or 'closed'; the other bits are kept.
    """
    _check_byte(outputs, 'outputs')
    if command not in GRIPPER_COMMANDS:
        raise ProtocolError(f'gripper command must be one of {GRIPPER_COMMANDS}, got {command!r}')
    bits = {'off': 0, 'open': GRIPPER_ENABLED | GRIPPER_OPEN, 'closed': GRIPPER_ENABLED}[command]
    return (outputs & ~(GRIPPER_ENABLED | GRIPPER_OPEN)) | bits


def decode_gripper(outputs: int) -> str:
    """Return the gripper command joint 4's output bits ``outputs`` carry: off, open or closed."""
    _check_byte(outputs, 'outputs')
    if not outputs & GRIPPER_ENABLED:
        return 'off'
    return 'open' if outputs & GRIPPER_OPEN else 'closed'


def decode_inputs(inputs: int, channels: int = len(INPUT_CHANNELS)) -> tuple[bool, ...]:
    """Return the first ``channels`` (0..7) input channels of a reply's ``data[7]``, bit n = n."""
    _check_byte(inputs, 'inputs')
    if isinstance(channels, bool) or not isinstance(channels, int) or not 0 <= channels <= 7:
        raise ProtocolError(f'channels must be an int in 0..7, got {channels!r}')
    return tuple(bool(inputs & (1 << n)) for n in range(channels))
