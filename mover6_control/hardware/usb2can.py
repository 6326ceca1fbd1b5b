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

A cable that comes back: a pulled adapter makes reads fail and writes fail or block. A write
never blocks longer than ``write_timeout`` (pyserial's); any failed read or write closes the port
(closing never waits on the device) and the bus says so (``connected`` False, ``link_error``
why) instead of raising on every call afterwards; ``reopen`` opens the same path again once the
device is back (the driver calls it with back-off, ``hardware.link``).
"""

from __future__ import annotations

import collections
import os
import select
import threading
import time
from typing import Iterable, Optional

import can
from mover6_control.hardware.protocol import ProtocolError
import serial

BAUDRATE = 460800
"""The serial speed of the CPR USB2CAN adapter [baud]."""

FRAME_LENGTH = 11
WRITE_TIMEOUT = 0.02
"""[s] a write may block this long (one frame takes 0.24 ms at 460800 baud) before it fails."""
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
                 accept_ids: Optional[Iterable[int]] = None,
                 write_timeout: float = WRITE_TIMEOUT, **kwargs: object) -> None:
        kwargs.pop('bitrate', None)          # the CAN bit rate is the adapter's, not ours
        self._baudrate, self._poll, self._write_timeout = baudrate, poll, write_timeout
        self._accept_ids = accept_ids
        self._serial = None
        self._channel = channel
        self.link_error = ''
        self.reopened = 0
        try:
            self._serial = self._open()
        except (serial.SerialException, OSError, ValueError) as err:
            raise can.CanInitializationError(
                f'cannot open the USB2CAN adapter on {channel!r}: {err}') from err
        self.decoder = SerialFrameDecoder(accept_ids)
        self.channel_info = f'CPR USB2CAN on {channel}'
        self._pending = collections.deque()
        self._write_lock = threading.Lock()
        super().__init__(channel=channel, **kwargs)

    def _open(self) -> serial.SerialBase:
        return serial.serial_for_url(self._channel, baudrate=self._baudrate, timeout=self._poll,
                                     write_timeout=self._write_timeout)

    @property
    def connected(self) -> bool:
        """Tell whether the port is open (False once a read or write failed, until reopen)."""
        return self._serial is not None

    def _lose(self, what: str, err: BaseException) -> None:
        """Close the port after a failed ``what`` (never waiting on the device); keep why."""
        port, self._serial = self._serial, None
        self.link_error = f'USB2CAN {what} failed: {err}'
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass                         # the device is gone: nothing left to close

    def reopen(self) -> bool:
        """
        Open the port again after a loss; return whether it is open.

        The decoder and the frames not yet taken start over (a partial frame of the old link is
        no part of the new one). A device that is not back yet leaves the bus as it was.
        """
        if self._serial is not None:
            return True
        try:
            port = self._open()
        except (serial.SerialException, OSError, ValueError) as err:
            self.link_error = f'USB2CAN reopen failed: {err}'
            return False
        self.decoder = SerialFrameDecoder(self._accept_ids)
        self._pending.clear()
        self._serial = port
        self.link_error = ''
        self.reopened += 1
        return True

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
        with self._write_lock:
            port = self._serial
            if port is None:
                raise can.CanOperationError(f'USB2CAN link lost: {self.link_error}')
            try:
                self._write(port, frame)
            except (serial.SerialException, OSError) as err:   # a timeout too: never blocks
                self._lose('write', err)
                raise can.CanOperationError(self.link_error) from err

    def _write(self, port: serial.SerialBase, frame: bytes) -> None:
        """
        Write ``frame``, waiting at most ``write_timeout`` [s] while the device takes no bytes.

        The port's descriptor is non-blocking (pyserial opens it so): the deadline counts only
        while a write would block. pyserial's own write timeout also fires when the writing
        thread was merely held up for longer than it after writing everything (on a loaded
        machine: a link taken for lost that was not).
        """
        try:
            fd = port.fileno()
        except (AttributeError, NotImplementedError, serial.SerialException):
            port.write(frame)                # a pyserial URL without a descriptor (tests)
            return
        view = memoryview(frame)
        deadline = time.monotonic() + self._write_timeout
        while view:
            try:
                view = view[os.write(fd, view):]
                continue
            except BlockingIOError:
                pass
            left = deadline - time.monotonic()
            if left <= 0.0:
                raise serial.SerialTimeoutException(
                    f'write timeout: the adapter took no bytes for {self._write_timeout} s')
            select.select([], [fd], [], left)

    def _recv_internal(self, timeout: Optional[float]) -> tuple[Optional[can.Message], bool]:
        """Return the next decoded frame, or None once ``timeout`` [s] passed (None: wait)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._pending:
            port = self._serial
            if port is None:
                raise can.CanOperationError(f'USB2CAN link lost: {self.link_error}')
            try:
                waiting = port.in_waiting
                if not waiting and deadline is not None and time.monotonic() >= deadline:
                    return None, False       # a poll (timeout 0) returns at once
                chunk = port.read(max(1, waiting))
            except (serial.SerialException, OSError, TypeError) as err:
                # TypeError: pyserial reading a port closed under it by another thread
                self._lose('read', err)
                raise can.CanOperationError(self.link_error) from err
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
        """Close the serial port (never waits on a device that went)."""
        super().shutdown()
        port, self._serial = self._serial, None
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass
