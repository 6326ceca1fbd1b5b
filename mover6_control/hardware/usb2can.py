"""
The vendor's CPR USB2CAN adapter: CAN frames as 11-byte serial frames, and a python-can bus on it.

The adapter is a USB serial port (``/dev/ttyUSB0``, 460800 baud). Each CAN frame, in both
directions, is 11 bytes: ``[id, dlc, d0 .. d7, checksum]``, the data zero-padded to 8 bytes and the
checksum the sum of bytes 0..9 modulo 256. The ID is one byte carrying the CAN ID as it is: the
vendor's serial reader and writer (``cpr_RS232CAN.cpp`` of the Mover4 demo, CPR-Robots/Mover4)
write ``id`` into byte 0 and keep received frames in a table of 256 entries indexed by that byte
(refusing any ID above 255), so the adapter carries IDs 0x00..0xFF only; the Mover6's IDs (0x10 ..
0x61) fit, and an ID above 0xFF is refused here with a clear error instead of being truncated.
The vendor reader takes a byte as the start of a frame only when it is a known reply ID (its
Mover4 list: 0x11, 0x21, 0x31, 0x41, 0x51), drops a frame whose checksum is wrong, and starts
over ("out of sync") when more than 2 ms pass between two bytes. ``SerialFrameDecoder`` does the
same (the ID filter optional), counts what it drops, and also resynchronises inside a burst by
sliding one byte on a bad checksum or an impossible length, so one corrupted byte loses one frame,
never the stream, and is never decoded as a position.

``Usb2CanBus`` is a ``can.BusABC`` over pyserial (``serial.serial_for_url``, so a pty's device
path or ``/dev/ttyUSB0`` alike): standard 11-bit data frames only, as the modules speak.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Iterable, Optional

import can
from mover6_control.hardware.protocol import ProtocolError
import serial

BAUDRATE = 460800
"""The serial speed of the CPR USB2CAN adapter [baud]."""

FRAME_LENGTH = 11
RESYNC_GAP = 0.002
"""A pause between two bytes longer than this [s] ends a partial frame (the vendor's rule)."""


def checksum(frame: bytes) -> int:
    """Return the checksum of a serial frame's first ten bytes: their sum modulo 256."""
    return sum(frame[:10]) % 256


def encode_serial_frame(can_id: int, data: bytes) -> bytes:
    """Return the 11 serial bytes that carry a CAN frame of ``can_id`` (0..0xFF) and ``data``."""
    data = bytes(data)
    if isinstance(can_id, bool) or not isinstance(can_id, int) or not 0 <= can_id <= 0xFF:
        raise ProtocolError(f'the USB2CAN adapter carries CAN IDs 0..0xFF in one byte, '
                            f'got {can_id!r}')
    if len(data) > 8:
        raise ProtocolError(f'a CAN frame carries at most 8 data bytes, got {len(data)}')
    head = bytes((can_id, len(data))) + data.ljust(8, b'\x00')
    return head + bytes((checksum(head),))


class SerialFrameDecoder:
    """
    Cut a serial byte stream into CAN frames, dropping what does not check.

    ``feed`` takes whatever the port gave and the time it arrived [s] and returns the complete,
    valid frames as ``(can_id, data)`` with ``data`` cut to the frame's length. ``dropped`` counts
    frames lost (a bad checksum, an impossible length, a frame cut short by a pause), ``skipped``
    the bytes thrown away while looking for the next frame. ``accept_ids``, if given, are the only
    IDs a frame may start with (the vendor reader's rule), which makes resynchronising faster.
    """

    def __init__(self, accept_ids: Optional[Iterable[int]] = None,
                 gap: Optional[float] = RESYNC_GAP) -> None:
        self.accept_ids = None if accept_ids is None else frozenset(accept_ids)
        self.gap = gap
        self.dropped = 0
        self.skipped = 0
        self.frames = 0
        self._buffer = bytearray()
        self._last = None
        self._in_sync = True

    def _lose(self, n: int) -> None:
        """Throw away the first ``n`` buffered bytes; the first loss of a run drops a frame."""
        if self._in_sync:
            self.dropped += 1
            self._in_sync = False
        self.skipped += n
        del self._buffer[:n]

    def feed(self, chunk: bytes, now: float) -> list[tuple[int, bytes]]:
        """Add ``chunk`` received at ``now`` [s]; return the frames it completes."""
        if self.gap is not None and self._last is not None and self._buffer and \
                now - self._last > self.gap:
            self._lose(len(self._buffer))    # a partial frame cut short: out of sync
            self._in_sync = True             # the pause itself marks the next frame's start
        self._last = now
        self._buffer += chunk
        out = []
        while self._buffer:
            if self.accept_ids is not None and self._buffer[0] not in self.accept_ids:
                self._lose(1)
                continue
            if len(self._buffer) < FRAME_LENGTH:
                break
            frame = bytes(self._buffer[:FRAME_LENGTH])
            if frame[1] > 8 or checksum(frame) != frame[10]:
                self._lose(1)                # slide one byte and try again
                continue
            del self._buffer[:FRAME_LENGTH]
            self._in_sync = True
            self.frames += 1
            out.append((frame[0], frame[2:2 + frame[1]]))
        return out


class Usb2CanBus(can.BusABC):
    """
    A python-can bus on the CPR USB2CAN adapter (or anything speaking its framing, e.g. a pty).

    ``channel`` is a serial device path or a pyserial URL. Sending writes one 11-byte frame under
    a lock (the driver's control thread and its service calls share the bus); receiving reads what
    the port has and decodes it with ``SerialFrameDecoder``. The port is read with a fixed
    timeout of ``poll`` [s] (changing a port's timeout reconfigures the device), so a ``recv``
    may return up to ``poll`` after its own timeout. Serial failures surface as python-can
    errors (``CanInitializationError`` on open, ``CanOperationError`` later).
    """

    def __init__(self, channel: str, baudrate: int = BAUDRATE, poll: float = 0.02,
                 accept_ids: Optional[Iterable[int]] = None, **kwargs: object) -> None:
        kwargs.pop('bitrate', None)          # the CAN bit rate is the adapter's, not ours
        try:
            self._serial = serial.serial_for_url(channel, baudrate=baudrate, timeout=poll)
        except (serial.SerialException, ValueError) as err:
            raise can.CanInitializationError(
                f'cannot open the USB2CAN adapter on {channel!r}: {err}') from err
        self.decoder = SerialFrameDecoder(accept_ids)
        self.channel_info = f'CPR USB2CAN on {channel}'
        self._channel = channel
        self._pending = collections.deque()
        self._write_lock = threading.Lock()
        super().__init__(channel=channel, **kwargs)

    @property
    def dropped(self) -> int:
        """Frames dropped by the decoder so far (bad checksum, bad length, cut short)."""
        return self.decoder.dropped

    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        """Write one CAN frame; only standard (11-bit) data frames with an ID up to 0xFF."""
        if msg.is_extended_id or msg.is_remote_frame or msg.is_error_frame or msg.is_fd:
            raise can.CanOperationError('the USB2CAN adapter sends standard data frames only')
        try:
            frame = encode_serial_frame(msg.arbitration_id, bytes(msg.data[:msg.dlc]))
        except ProtocolError as err:
            raise can.CanOperationError(str(err)) from err
        try:
            with self._write_lock:
                self._serial.write(frame)
        except (serial.SerialException, OSError) as err:
            raise can.CanOperationError(f'USB2CAN write failed: {err}') from err

    def _recv_internal(self, timeout: Optional[float]) -> tuple[Optional[can.Message], bool]:
        """Return the next decoded frame, or None once ``timeout`` [s] passed (None: wait)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._pending:
            try:
                waiting = self._serial.in_waiting
                if not waiting and deadline is not None and time.monotonic() >= deadline:
                    return None, False       # a poll (timeout 0) returns at once
                chunk = self._serial.read(max(1, waiting))
            except (serial.SerialException, OSError) as err:
                raise can.CanOperationError(f'USB2CAN read failed: {err}') from err
            if chunk:
                stamp = time.time()
                for can_id, data in self.decoder.feed(chunk, time.monotonic()):
                    self._pending.append(can.Message(
                        timestamp=stamp, arbitration_id=can_id, is_extended_id=False,
                        dlc=len(data), data=data, channel=self._channel, is_rx=True))
            elif deadline is not None and time.monotonic() >= deadline:
                return None, False
            if deadline is not None and not self._pending and time.monotonic() >= deadline:
                return None, False
        return self._pending.popleft(), False

    def shutdown(self) -> None:
        """Close the serial port."""
        super().shutdown()
        self._serial.close()
