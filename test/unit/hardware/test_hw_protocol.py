"""
The Mover6 CAN codec, byte for byte against frames written out by hand from the vendor's sources.

Each expected frame below was written from ``MotorModule.cpp`` (``Command_SetJoint``,
``Command_ResetError``, ``Command_EnableMotor``, ``Command_DisableMotor``,
``Command_StartReferencing``, ``Command_SetZeroPosition``, ``get_CurrentPosition``) and the Mover6
user guide's error-flag table, not computed with the code under test.
"""

from hypothesis import given, strategies as st
from mover6_control.hardware import protocol as p
import pytest


def test_ids_of_the_six_modules():
    assert [p.command_id(j) for j in range(1, 7)] == [0x10, 0x20, 0x30, 0x40, 0x50, 0x60]
    assert [p.reply_id(j) for j in range(1, 7)] == [0x11, 0x21, 0x31, 0x41, 0x51, 0x61]
    assert p.joint_of_id(0x10) == (1, False)
    assert p.joint_of_id(0x31) == (3, True)
    assert p.joint_of_id(0x61) == (6, True)
    assert p.BITRATE == 500000


@pytest.mark.parametrize('bad', [0, 7, -1, True, 1.0, '1'])
def test_no_module_outside_1_to_6(bad):
    with pytest.raises(p.ProtocolError, match='joint must be one of'):
        p.command_id(bad)


@pytest.mark.parametrize('can_id', [0x00, 0x01, 0x12, 0x1F, 0x70, 0x71, 0x7FF, -1])
def test_foreign_ids_are_refused(can_id):
    with pytest.raises(p.ProtocolError, match='no Mover6 module'):
        p.joint_of_id(can_id)


# (ticks + offset, counter, digital outputs) -> the 8 bytes on the wire.
SETPOINTS = [
    ((0, 0, 0), '14 00 00 00 00 00 00 00'),
    ((1500, 7, 0), '14 00 00 00 05 DC 07 00'),            # J5: 1000 ticks + offset 500
    ((-1, 42, 0x03), '14 00 FF FF FF FF 2A 03'),          # gripper open + enabled (J4 outputs)
    ((-4000, 255, 0), '14 00 FF FF F0 60 FF 00'),
    ((0x12345678, 256, 0x80), '14 00 12 34 56 78 00 80'),  # the counter wraps at 256
    ((300, 300, 0), '14 00 00 00 01 2C 2C 00'),
    ((2 ** 31 - 1, 1, 0), '14 00 7F FF FF FF 01 00'),
    ((-2 ** 31, 1, 0), '14 00 80 00 00 00 01 00'),
]


@pytest.mark.parametrize('args,wire', SETPOINTS)
def test_setpoint_byte_for_byte(args, wire):
    data = p.encode_setpoint(*args)
    assert data == bytes.fromhex(wire)
    cmd = p.decode_command(bytes.fromhex(wire))
    assert cmd == p.Command('setpoint', args[0], args[1] & 0xFF, args[2])


# The fixed commands, as MotorModule.cpp sends them (DLC 2, set zero DLC 4).
COMMANDS = [
    ('reset', p.RESET_ERRORS, '01 06'),
    ('enable', p.ENABLE, '01 09'),
    ('disable', p.DISABLE, '01 0A'),
    ('reference', p.START_REFERENCING, '01 0B'),
    ('set_zero', p.SET_ZERO, '01 08 00 00'),
]


@pytest.mark.parametrize('kind,const,wire', COMMANDS)
def test_commands_byte_for_byte(kind, const, wire):
    assert const == bytes.fromhex(wire)
    assert p.COMMAND_FRAMES[kind] == const
    value = 0 if kind == 'set_zero' else None          # set zero carries its new value
    assert p.decode_command(bytes.fromhex(wire)) == p.Command(kind, position=value)


@pytest.mark.parametrize('value,wire', [(0, '01 08 00 00'), (500, '01 08 01 F4'),
                                        (509, '01 08 01 FD'), (0x7D00, '01 08 7D 00')])
def test_set_zero_carries_its_value_big_endian(value, wire):
    assert p.encode_set_zero(value) == bytes.fromhex(wire)
    assert p.decode_command(bytes.fromhex(wire)) == p.Command('set_zero', position=value)


@pytest.mark.parametrize('value', [-1, 0x10000, 1.0, True, None])
def test_set_zero_refuses_a_value_off_two_bytes(value):
    with pytest.raises(p.ProtocolError):
        p.encode_set_zero(value)


@pytest.mark.parametrize('wire', [
    '01 09 00 00 00 00 00 00',      # enable with DLC 8: the module ignores a wrong length
    '01 08',                        # set zero needs DLC 4
    '01 06 00',
    '14 00 00 00 00 00 00',         # a set-point one byte short
    '14 00 00 00 00 00 00 00 00',
    '01 07',                        # no such command
    '15 00 00 00 00 00 00 00',
    '',
])
def test_wrong_length_or_unknown_command_is_refused(wire):
    with pytest.raises(p.ProtocolError):
        p.decode_command(bytes.fromhex(wire))


# (error flags, position with offset, timestamp, inputs) -> the module's 8 reply bytes.
REPLIES = [
    ((0x04, 509, 0x33, 0x80), '04 00 00 01 FD 33 00 80'),   # J6 at 0 ticks, referenced
    ((0x1C, -4000, 0x12, 0x00), '1C FF FF F0 60 12 00 00'),  # just powered up
    ((0x00, 0x0A0B0C0D, 0xFF, 0x81), '00 0A 0B 0C 0D FF 00 81'),
]


@pytest.mark.parametrize('args,wire', REPLIES)
def test_reply_byte_for_byte(args, wire):
    assert p.encode_reply(*args) == bytes.fromhex(wire)
    reply = p.decode_reply(bytes.fromhex(wire))
    assert (reply.error_flags, reply.position, reply.timestamp, reply.inputs) == args
    assert reply.referenced == bool(args[3] & 0x80)


def test_reply_ignores_byte_6_as_the_vendor_does():
    assert p.decode_reply(bytes.fromhex('00 00 00 00 01 05 EE 00')).position == 1


@pytest.mark.parametrize('wire', ['04 00 00 01 FD 33 00', '04 00 00 01 FD 33 00 80 00', ''])
def test_reply_of_wrong_length_is_refused(wire):
    with pytest.raises(p.ProtocolError, match='8 bytes'):
        p.decode_reply(bytes.fromhex(wire))


@pytest.mark.parametrize('kwargs,match', [
    ({'position': 2 ** 31, 'counter': 0}, 'int32'),
    ({'position': 1.5, 'counter': 0}, 'int32'),
    ({'position': 0, 'counter': 0, 'digital_out': 256}, 'digital_out'),
    ({'position': 0, 'counter': None}, 'counter'),
])
def test_setpoint_out_of_range_is_refused(kwargs, match):
    with pytest.raises(p.ProtocolError, match=match):
        p.encode_setpoint(**kwargs)


MOVER6_FLAGS = [(0x01, 'brown_out'), (0x02, 'velocity_lag'), (0x04, 'motor_not_enabled'),
                (0x08, 'comm_watchdog'), (0x10, 'position_lag'), (0x20, 'encoder'),
                (0x40, 'over_current'), (0x80, 'can')]
CAN_V2_FLAGS = [(0x01, 'over_temperature'), (0x02, 'estop_or_low_supply'),
                (0x04, 'motor_not_enabled'), (0x08, 'comm_watchdog'), (0x10, 'position_lag'),
                (0x20, 'encoder'), (0x40, 'driver'), (0x80, 'over_current')]


@pytest.mark.parametrize('bit,name', MOVER6_FLAGS)
def test_every_mover6_flag_by_name(bit, name):
    assert p.flag_names(bit) == (name,)
    assert p.flag_names(bit, 'mover6') == (name,)
    assert p.decode_reply(bytes((bit, 0, 0, 0, 0, 0, 0, 0))).error_flags == bit


@pytest.mark.parametrize('bit,name', CAN_V2_FLAGS)
def test_every_can_v2_flag_by_name(bit, name):
    assert p.flag_names(bit, 'can_v2') == (name,)


def test_flag_combinations_and_the_power_up_state():
    assert p.flag_names(0x00) == ()
    assert p.flag_names(0x1C) == ('motor_not_enabled', 'comm_watchdog', 'position_lag')
    assert p.flag_names(0xFF) == tuple(name for _, name in MOVER6_FLAGS)
    assert p.flag_names(0xC3, 'can_v2') == ('over_temperature', 'estop_or_low_supply',
                                            'driver', 'over_current')
    with pytest.raises(p.ProtocolError, match='firmware'):
        p.flag_names(0x01, 'mover4')
    with pytest.raises(p.ProtocolError, match='flags'):
        p.flag_names(0x100)


def test_protocol_error_is_a_value_error():
    assert issubclass(p.ProtocolError, ValueError)


@given(st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 10 ** 6), st.integers(0, 255))
def test_setpoint_round_trip(position, counter, dout):
    cmd = p.decode_command(p.encode_setpoint(position, counter, dout))
    assert (cmd.position, cmd.counter, cmd.digital_out) == (position, counter % 256, dout)


@given(st.integers(0, 255), st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 255),
       st.integers(0, 255))
def test_reply_round_trip(flags, position, stamp, inputs):
    r = p.decode_reply(p.encode_reply(flags, position, stamp, inputs))
    assert (r.error_flags, r.position, r.timestamp, r.inputs) == (flags, position, stamp, inputs)
