"""
The CPR USB2CAN serial framing, its decoder, and ``Usb2CanBus`` over a real pty with pyserial.

The 11-byte frames are written out by hand from the vendor's serial adapter code
(``cpr_RS232CAN.cpp``: ``[id, dlc, d0..d7, sum of bytes 0..9 mod 256]``).
"""

import os
import time

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.bus import open_bus
from mover6_control.hardware.usb2can import (
    encode_serial_frame, SerialFrameDecoder, Usb2CanBus, WRITE_TIMEOUT)
import pytest

# J1 set-point: J5's 1000 ticks + offset 500 sent to module 1, counter 7.
SETPOINT_J1 = bytes.fromhex('10 08 14 00 00 00 05 DC 07 00 14')
# Reset errors to module 3, DLC 2, zero-padded.
RESET_J3 = bytes.fromhex('30 02 01 06 00 00 00 00 00 00 39')
# Set zero to module 2, DLC 4.
SET_ZERO_J2 = bytes.fromhex('20 04 01 08 00 00 00 00 00 00 2D')
# Reply of module 6: motor not enabled, 509 (offset, 0 ticks), timestamp 0x33, referenced.
REPLY_J6 = bytes.fromhex('61 08 04 00 00 01 FD 33 00 80 1E')


def test_frames_byte_for_byte():
    assert encode_serial_frame(0x10, p.encode_setpoint(1500, 7)) == SETPOINT_J1
    assert encode_serial_frame(0x30, p.RESET_ERRORS) == RESET_J3
    assert encode_serial_frame(0x20, p.SET_ZERO) == SET_ZERO_J2
    assert encode_serial_frame(0x61, p.encode_reply(0x04, 509, 0x33, 0x80)) == REPLY_J6


def test_ids_that_do_not_fit_the_id_byte_are_refused():
    with pytest.raises(p.ProtocolError, match='0..0xFF'):
        encode_serial_frame(0x100, b'')
    with pytest.raises(p.ProtocolError, match='at most 8'):
        encode_serial_frame(0x10, bytes(9))


def test_good_frames_whole_and_byte_by_byte():
    dec = SerialFrameDecoder()
    assert dec.feed(REPLY_J6 + RESET_J3, 0.0) == [(0x61, REPLY_J6[2:10]), (0x30, b'\x01\x06')]
    t = 1.0
    out = []
    for byte in SET_ZERO_J2:
        t += 0.0001
        out += dec.feed(bytes((byte,)), t)
    assert out == [(0x20, p.SET_ZERO)]
    assert (dec.dropped, dec.skipped, dec.frames) == (0, 0, 3)


def test_bad_checksum_is_dropped_counted_and_the_next_frame_kept():
    bad = REPLY_J6[:10] + bytes(((REPLY_J6[10] + 1) % 256,))
    dec = SerialFrameDecoder()
    assert dec.feed(bad + SETPOINT_J1, 0.0) == [(0x10, SETPOINT_J1[2:10])]
    assert dec.dropped == 1 and dec.skipped == 11


def test_a_corrupted_byte_is_never_decoded_as_a_position():
    corrupt = bytearray(REPLY_J6)
    corrupt[5] ^= 0x40                      # a position byte flipped on the wire
    dec = SerialFrameDecoder()
    out = dec.feed(bytes(corrupt) + REPLY_J6 + RESET_J3, 0.0)
    assert out == [(0x61, REPLY_J6[2:10]), (0x30, b'\x01\x06')]
    assert dec.dropped == 1


def test_impossible_length_is_dropped():
    head = bytes((0x11, 9)) + bytes(8)
    frame = head + bytes((sum(head) % 256,))
    dec = SerialFrameDecoder()
    assert dec.feed(frame + RESET_J3, 0.0) == [(0x30, b'\x01\x06')]
    assert dec.dropped == 1


def test_truncated_frame_then_a_pause_resynchronises():
    dec = SerialFrameDecoder()
    assert dec.feed(REPLY_J6[:6], 0.0) == []
    assert dec.feed(SETPOINT_J1, 0.010) == [(0x10, SETPOINT_J1[2:10])]
    assert dec.dropped == 1 and dec.skipped == 6


def test_truncated_frame_without_a_pause_resynchronises_by_sliding():
    dec = SerialFrameDecoder()
    assert dec.feed(REPLY_J6[:6] + SETPOINT_J1 + RESET_J3, 0.0) == \
        [(0x10, SETPOINT_J1[2:10]), (0x30, b'\x01\x06')]
    assert dec.dropped == 1 and dec.skipped == 6


def test_a_frame_split_by_a_long_pause_is_dropped_as_the_vendor_does():
    dec = SerialFrameDecoder()
    assert dec.feed(RESET_J3[:5], 0.0) == []
    assert dec.feed(RESET_J3[5:], 0.003) == []
    assert dec.dropped == 1
    assert dec.feed(RESET_J3[:5], 1.0) + dec.feed(RESET_J3[5:], 1.001) == [(0x30, b'\x01\x06')]


def test_garbage_between_frames():
    dec = SerialFrameDecoder()
    garbage = bytes.fromhex('AA 55 00 FF 13 61 08')
    assert dec.feed(REPLY_J6 + garbage + REPLY_J6, 0.0) == [(0x61, REPLY_J6[2:10])] * 2
    assert dec.dropped == 1 and dec.skipped == len(garbage)


def test_accepted_ids_skip_foreign_start_bytes():
    dec = SerialFrameDecoder(accept_ids=[p.reply_id(j) for j in range(1, 7)])
    out = dec.feed(bytes.fromhex('00 13 77') + RESET_J3 + REPLY_J6, 0.0)
    assert out == [(0x61, REPLY_J6[2:10])]
    assert dec.skipped == 3 + 11


@pytest.fixture
def pty_bus():
    """Yield a Usb2CanBus on the slave side of a fresh pty and the master fd (the adapter)."""
    master, slave = os.openpty()
    bus = Usb2CanBus(os.ttyname(slave))
    yield bus, master
    bus.shutdown()
    os.close(slave)
    os.close(master)


def _read_exactly(fd, n):
    out = b''
    while len(out) < n:
        out += os.read(fd, n - len(out))
    return out


def test_bus_sends_the_frame_on_the_pty(pty_bus):
    bus, master = pty_bus
    bus.send(can.Message(arbitration_id=0x10, is_extended_id=False,
                         data=p.encode_setpoint(1500, 7)))
    bus.send(can.Message(arbitration_id=0x30, is_extended_id=False, data=p.RESET_ERRORS))
    assert _read_exactly(master, 22) == SETPOINT_J1 + RESET_J3


def test_bus_receives_from_the_pty_and_drops_corruption(pty_bus):
    bus, master = pty_bus
    corrupt = bytearray(REPLY_J6)
    corrupt[3] ^= 0x01
    os.write(master, bytes(corrupt) + REPLY_J6)
    msg = bus.recv(timeout=10.0)
    assert msg is not None
    assert (msg.arbitration_id, msg.dlc, bytes(msg.data)) == (0x61, 8, REPLY_J6[2:10])
    assert not msg.is_extended_id
    assert bus.dropped == 1
    assert bus.recv(timeout=0.05) is None


def test_bus_refuses_what_the_adapter_cannot_carry(pty_bus):
    bus, _ = pty_bus
    with pytest.raises(can.CanOperationError, match='standard'):
        bus.send(can.Message(arbitration_id=0x10, is_extended_id=True, data=b''))
    with pytest.raises(can.CanOperationError, match='0..0xFF'):
        bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b''))


def test_open_bus_by_interface_name():
    master, slave = os.openpty()
    try:
        bus = open_bus('cpr_usb2can', os.ttyname(slave))
        assert isinstance(bus, Usb2CanBus)
        bus.shutdown()
    finally:
        os.close(slave)
        os.close(master)
    a = open_bus('virtual', 'test_open_bus_by_interface_name')
    b = open_bus('virtual', 'test_open_bus_by_interface_name')
    try:
        a.send(can.Message(arbitration_id=0x20, is_extended_id=False, data=p.ENABLE))
        msg = b.recv(timeout=10.0)
        assert (msg.arbitration_id, bytes(msg.data)) == (0x20, p.ENABLE)
    finally:
        a.shutdown()
        b.shutdown()


def test_open_bus_errors_are_clear():
    with pytest.raises(InvalidInputError, match='can_interface must be one of'):
        open_bus('nonsense', 'can0')
    with pytest.raises(InvalidInputError, match='bitrate'):
        open_bus('virtual', 'x', bitrate=0)
    with pytest.raises(can.CanInitializationError, match='cannot open the USB2CAN'):
        open_bus('cpr_usb2can', '/dev/no_such_adapter')


def test_a_write_never_blocks_when_the_adapter_takes_no_bytes(pty_bus):
    bus, _ = pty_bus                 # nobody reads the master: the pty's buffer fills up
    frame = can.Message(arbitration_id=0x10, is_extended_id=False, data=p.encode_setpoint(0, 1))
    longest, failed = 0.0, None
    for _ in range(20000):
        start = time.monotonic()
        try:
            bus.send(frame)
        except can.CanOperationError as err:
            failed = str(err)
        longest = max(longest, time.monotonic() - start)
        if failed:
            break
    assert failed and 'write failed' in failed
    assert longest < WRITE_TIMEOUT + 0.2
    assert not bus.connected            # a write that blocks is a link that went
    with pytest.raises(can.CanOperationError, match='link lost'):
        bus.recv(timeout=0.0)


def test_a_lost_port_is_reopened_on_the_same_path(tmp_path):
    link = tmp_path / 'adapter'
    master, slave = os.openpty()
    os.symlink(os.ttyname(slave), link)
    bus = Usb2CanBus(str(link))
    try:
        os.close(master)                 # the adapter pulled: reads fail
        os.unlink(link)
        with pytest.raises(can.CanOperationError, match='read failed'):
            bus.recv(timeout=0.5)
        assert not bus.connected and 'read failed' in bus.link_error
        assert not bus.reopen() and 'reopen failed' in bus.link_error   # not back yet
        os.close(slave)
        master, slave = os.openpty()     # the adapter back, at the same path
        os.symlink(os.ttyname(slave), link)
        assert bus.reopen() and bus.connected and bus.reopened == 1
        os.write(master, REPLY_J6)
        msg = bus.recv(timeout=5.0)
        assert msg is not None and bytes(msg.data) == REPLY_J6[2:10]
    finally:
        bus.shutdown()
        bus.shutdown()                   # twice: still no error
        os.close(slave)
        os.close(master)
