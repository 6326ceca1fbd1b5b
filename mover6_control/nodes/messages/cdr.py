"""
The serialized (CDR) form of the two 100 Hz messages, written and read without rclpy's conversion.

/joint_states (sensor_msgs/JointState) and /JointJog (control_msgs/JointJog) go every 10 ms
between the sim bridge (or the driver) and the controller. rclpy builds a Python message object
per sample and converts it field by field to the C struct and back; on a node that does little
else that conversion is a large part of its idle CPU (``./run.sh bench idle``).
So the nodes publish bytes (``Publisher.publish`` takes a serialized message) built here with
one ``struct`` call, and subscribe with ``raw=True`` and read the few fields they need here.

The layout is the one rmw_fastrtps writes and reads (XCDR1): a 4-byte encapsulation header
(``00 01``: little endian, ``00 00``: big endian, then two option bytes), then the fields in
order, each primitive aligned to its own size counted from the end of that header; a string is
a uint32 length that counts its terminating NUL, the bytes, the NUL; a sequence is a uint32
count, then the elements. ``test/node/test_cdr.py`` checks the bytes against rclpy's own
``serialize_message`` and the readings against ``deserialize_message``.

A reader raises ``ValueError`` on anything it does not expect (another layout, a truncated
sample): the node then takes rclpy's own deserialization and its usual checks, so an odd but
valid message is never lost and a malformed one is refused with the reason.
"""

import struct
from typing import Optional, Sequence

CDR_LE = b'\x00\x01\x00\x00'
_HEADER = 4                  # the encapsulation header; alignment counts from its end
_U32 = {'<': struct.Struct('<I'), '>': struct.Struct('>I')}
_STAMP = {'<': struct.Struct('<iI'), '>': struct.Struct('>iI')}


class _Packer:
    """
    One ``struct.Struct`` for a whole message whose variable part is a stamp and doubles.

    ``literal()`` adds constant bytes (names, counts, padding), ``field(fmt)`` a variable field
    (its values are passed to ``pack`` in order); ``pack`` returns the message's bytes.
    """

    def __init__(self):
        self.buf = bytearray()
        self._format = ['<']
        self._literals = []      # per part: its constant bytes, or None for a variable field
        self._fixed = bytearray()
        self.literal(CDR_LE)

    def _flush(self):
        if self._fixed:
            self._format.append(f'{len(self._fixed)}s')
            self._literals.append(bytes(self._fixed))
            self._fixed = bytearray()

    def literal(self, data: bytes) -> None:
        """Add constant bytes."""
        self.buf.extend(data)
        self._fixed.extend(data)

    def pad(self, size: int) -> None:
        """Add zero bytes up to the alignment ``size``."""
        n = -(len(self.buf) - _HEADER) % size
        self.literal(bytes(n))

    def field(self, fmt: str, size: int) -> None:
        """Add a variable field of struct format ``fmt`` (``size`` bytes)."""
        self._flush()
        self._format.append(fmt)
        self.buf.extend(bytes(size))
        self._literals.append(None)

    def build(self):
        """Return ``(Struct, literals)``: literals[i] is the constant of part i or None."""
        self._flush()
        return struct.Struct(''.join(self._format)), self._literals


def _literal_string(packer: _Packer, text: str) -> None:
    data = text.encode('utf-8') + b'\x00'
    packer.pad(4)
    packer.literal(struct.pack('<I', len(data)) + data)


def _literal_strings(packer: _Packer, texts) -> None:
    packer.pad(4)
    packer.literal(struct.pack('<I', len(texts)))
    for text in texts:
        _literal_string(packer, text)


def _doubles(packer: _Packer, n: int) -> None:
    packer.pad(4)
    packer.literal(struct.pack('<I', n))
    if n:
        packer.pad(8)
        packer.field(f'{n}d', 8 * n)


class JointStateWriter:
    """
    Serialized sensor_msgs/JointState for fixed joint ``names`` and ``frame_id``.

    ``serialize(sec, nanosec, q, qd, effort)`` returns the bytes of a message with that stamp,
    ``position`` ``q``, ``velocity`` ``qd`` and ``effort`` (each one value per name; an empty
    ``effort`` when ``with_effort`` is False).
    """

    def __init__(self, names, frame_id: str = '', with_effort: bool = True):
        """Lay out the message once; only the stamp and the values change between samples."""
        n = len(names)
        if n == 0:
            raise ValueError('a JointState writer needs at least one joint name')
        p = _Packer()
        p.field('iI', 8)                       # header.stamp (offset 0: aligned)
        _literal_string(p, frame_id)
        _literal_strings(p, list(names))
        _doubles(p, n)                          # position
        _doubles(p, n)                          # velocity
        _doubles(p, n if with_effort else 0)    # effort
        self._struct, literals = p.build()
        # The constant parts in order: the encapsulation, then before position, before
        # velocity and before effort (with effort) or after velocity (without).
        self._c = [lit for lit in literals if lit is not None]
        self._effort = with_effort

    def serialize(self, sec: int, nanosec: int, q: Sequence[float], qd: Sequence[float],
                  effort: Optional[Sequence[float]] = None) -> bytes:
        """Return the serialized message (``q``, ``qd``, ``effort``: n values each)."""
        c = self._c
        if self._effort:
            return self._struct.pack(c[0], sec, nanosec, c[1], *q, c[2], *qd, c[3], *effort)
        return self._struct.pack(c[0], sec, nanosec, c[1], *q, c[2], *qd, c[3])


class JointJogWriter:
    """
    Serialized control_msgs/JointJog for fixed ``joint_names``: stamped, ``velocities`` only.

    ``displacements`` empty and ``duration`` 0, as the controller sends it.
    """

    def __init__(self, names, frame_id: str = ''):
        """Lay out the message once; only the stamp and the velocities change."""
        n = len(names)
        if n == 0:
            raise ValueError('a JointJog writer needs at least one joint name')
        p = _Packer()
        p.field('iI', 8)                  # header.stamp
        _literal_string(p, frame_id)
        _literal_strings(p, list(names))
        _doubles(p, 0)                    # displacements
        _doubles(p, n)                    # velocities
        p.pad(8)
        p.literal(struct.pack('<d', 0.0))   # duration
        self._struct, literals = p.build()
        self._c = [lit for lit in literals if lit is not None]

    def serialize(self, sec: int, nanosec: int, velocities: Sequence[float]) -> bytes:
        """Return the serialized message with this stamp and ``velocities`` (n values)."""
        c = self._c
        return self._struct.pack(c[0], sec, nanosec, c[1], *velocities, c[2])


class _Reader:
    """Bounds-checked reading of one CDR sample; raises ``ValueError`` when it runs out."""

    __slots__ = ('raw', 'o', 'e')

    def __init__(self, raw):
        if len(raw) < _HEADER or raw[0] != 0 or raw[1] not in (0, 1):
            raise ValueError('not a plain CDR sample')
        self.raw, self.o = raw, _HEADER
        self.e = '<' if raw[1] == 1 else '>'

    def align(self, size):
        self.o += -(self.o - _HEADER) % size

    def u32(self):
        self.align(4)
        if self.o + 4 > len(self.raw):
            raise ValueError('truncated sample')
        (value,) = _U32[self.e].unpack_from(self.raw, self.o)
        self.o += 4
        return value

    def string(self):
        n = self.u32()
        end = self.o + n
        if n == 0 or end > len(self.raw) or self.raw[end - 1] != 0:
            raise ValueError('bad string')
        text = self.raw[self.o:end - 1].decode('utf-8')
        self.o = end
        return text

    def doubles_at(self):
        """Skip a double sequence; return ``(count, offset of its first value)``."""
        n = self.u32()
        if n:
            self.align(8)
        start = self.o
        if start + 8 * n > len(self.raw):
            raise ValueError('truncated sequence')
        self.o += 8 * n
        return n, start


class _NamedArraysReader:
    """
    Read a stamped message of names then double sequences; the layout is cached per sender.

    A sender sends the same names every time: the bytes from the frame id to the end of the
    names are compared with the last sample's, and when they match (and the counts do) only the
    stamp and the doubles are unpacked.
    """

    n_sequences = 0    # double sequences after the names (subclass)

    def __init__(self):
        self._key = None          # bytes from frame_id to the end of the names
        self._cache = None        # (names, counts offsets, counts, Struct per sequence, offsets)

    def _parse(self, raw):
        r = _Reader(raw)
        if len(raw) < _HEADER + 8:
            raise ValueError('truncated sample')
        stamp = _STAMP[r.e].unpack_from(raw, r.o)
        r.o += 8
        key_start = r.o
        r.string()                                      # frame_id
        count = r.u32()
        if count > 4096:
            raise ValueError('too many names')
        names = tuple(r.string() for _ in range(count))
        key_end = r.o
        sequences = []
        for _ in range(self.n_sequences):
            r.align(4)
            count_at = r.o
            n, start = r.doubles_at()
            sequences.append((count_at, n, start))
        self._key = (r.e, key_start, bytes(raw[key_start:key_end]))
        self._cache = (names, tuple(
            (count_at, n, start, struct.Struct(f'{r.e}{n}d')) for count_at, n, start in
            sequences), r.o)
        return stamp

    def read(self, raw):
        """Return ``(sec, nanosec, names, [values of each sequence as a tuple])``."""
        key = self._key
        if (key is None or len(raw) < 12 or raw[1] != (1 if key[0] == '<' else 0)
                or not raw.startswith(key[2], key[1])):
            stamp = self._parse(raw)
        else:
            stamp = _STAMP[key[0]].unpack_from(raw, _HEADER)
            u32 = _U32[key[0]]
            names, sequences, end = self._cache
            if len(raw) < end or any(u32.unpack_from(raw, at)[0] != n
                                     for at, n, _, _ in sequences):
                stamp = self._parse(raw)
        names, sequences, _ = self._cache
        return (stamp[0], stamp[1], names,
                [s.unpack_from(raw, start) for _, _, start, s in sequences])


class JointStateReader(_NamedArraysReader):
    """Read ``(sec, nanosec, name, position, velocity)`` of a serialized JointState."""

    n_sequences = 2        # position, velocity (effort is not read)

    def read_state(self, raw: bytes) -> tuple[int, int, tuple, tuple, tuple]:
        """Return ``(sec, nanosec, names, positions, velocities)`` (tuples); ValueError if odd."""
        sec, nanosec, names, (position, velocity) = self.read(raw)
        return sec, nanosec, names, position, velocity


class JointJogReader(_NamedArraysReader):
    """Read ``(names, velocities)`` of a serialized JointJog (displacements, duration ignored)."""

    n_sequences = 2        # displacements, velocities

    def read_jog(self, raw: bytes) -> tuple[tuple, tuple, tuple]:
        """Return ``(names, displacements, velocities)`` (tuples); ValueError if odd."""
        _, _, names, (displacements, velocities) = self.read(raw)
        return names, displacements, velocities
