"""The hand-made CDR of the 100 Hz messages against rclpy's own (de)serialization."""

from builtin_interfaces.msg import Time
from control_msgs.msg import JointJog
from hypothesis import given, strategies as st
from mover6_control.nodes.messages import cdr
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

NAMES = [f'joint{i}' for i in range(1, 7)]
Q = [-1.5, -0.25, 0.0, 1e-9, 0.75, 1.5]
floats = st.floats(allow_nan=False, allow_infinity=False, width=64)
values6 = st.lists(floats, min_size=6, max_size=6)
names = st.lists(st.text(min_size=0, max_size=12).filter(lambda s: '\x00' not in s),
                 min_size=1, max_size=8)
stamps = st.tuples(st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 2 ** 32 - 1))


def joint_state(names, q, qd, effort, sec=0, nanosec=0, frame_id=''):
    """Return a JointState message."""
    msg = JointState(name=list(names), position=list(q), velocity=list(qd), effort=list(effort))
    msg.header.stamp = Time(sec=sec, nanosec=nanosec)
    msg.header.frame_id = frame_id
    return msg


@given(stamps, values6, values6, values6)
def test_joint_state_writer_is_what_rclpy_reads(stamp, q, qd, effort):
    """The writer's bytes deserialise (rclpy) to the same message, effort or not."""
    raw = cdr.JointStateWriter(NAMES).serialize(*stamp, q, qd, effort)
    assert deserialize_message(raw, JointState) == joint_state(NAMES, q, qd, effort, *stamp)
    raw = cdr.JointStateWriter(NAMES, with_effort=False).serialize(*stamp, q, qd)
    assert deserialize_message(raw, JointState) == joint_state(NAMES, q, qd, [], *stamp)


@given(names, st.text(max_size=9).filter(lambda s: '\x00' not in s), stamps)
def test_joint_state_writer_any_names_and_frame(joint_names, frame_id, stamp):
    """Names of any length (padding after each) and a frame id lay out as rclpy's."""
    n = len(joint_names)
    q, qd, effort = np.arange(n) * 0.5, -np.arange(n) * 0.25, np.ones(n)
    raw = cdr.JointStateWriter(joint_names, frame_id).serialize(*stamp, q, qd, effort)
    assert deserialize_message(raw, JointState) == joint_state(joint_names, q, qd, effort,
                                                               *stamp, frame_id=frame_id)


@given(names, stamps, st.data())
def test_joint_jog_writer_is_what_rclpy_reads(joint_names, stamp, data):
    """The JointJog writer: stamp, names, velocities; no displacements, duration 0."""
    v = data.draw(st.lists(floats, min_size=len(joint_names), max_size=len(joint_names)))
    raw = cdr.JointJogWriter(joint_names).serialize(*stamp, v)
    expected = JointJog(joint_names=joint_names, velocities=v)
    expected.header.stamp = Time(sec=stamp[0], nanosec=stamp[1])
    assert deserialize_message(raw, JointJog) == expected


@given(names, stamps, st.data(), st.booleans(), st.text(max_size=5).filter(
    lambda s: '\x00' not in s))
def test_joint_state_reader_reads_what_rclpy_writes(joint_names, stamp, data, with_velocity,
                                                    frame_id):
    """Any names, frame id, with or without velocities: the reader gives rclpy's values."""
    n = len(joint_names)
    q = data.draw(st.lists(floats, min_size=n, max_size=n))
    qd = data.draw(st.lists(floats, min_size=n, max_size=n)) if with_velocity else []
    msg = joint_state(joint_names, q, qd, [1.0] * n, *stamp, frame_id=frame_id)
    reader = cdr.JointStateReader()
    for _ in range(2):                  # the second read takes the cached layout
        sec, nanosec, got_names, position, velocity = reader.read_state(serialize_message(msg))
        assert (sec, nanosec) == stamp
        assert list(got_names) == joint_names
        assert list(position) == q and list(velocity) == qd


def test_reader_notices_a_new_layout_from_the_same_sender():
    """Other names, other counts, another frame id after a cached one: read afresh."""
    reader = cdr.JointStateReader()
    first = joint_state(NAMES, Q, Q, Q)
    assert reader.read_state(serialize_message(first))[2] == tuple(NAMES)
    other = joint_state(NAMES[::-1], Q, [], Q, 3, 4)
    assert reader.read_state(serialize_message(other)) == (3, 4, tuple(NAMES[::-1]), tuple(Q),
                                                           ())
    more = joint_state(NAMES + ['gripper'], Q + [0.5], Q + [0.0], [], frame_id='base_link')
    got = reader.read_state(serialize_message(more))
    assert got[2][-1] == 'gripper' and got[3][-1] == 0.5 and len(got[4]) == 7
    # Same names but the counts differ from the cached layout (fewer positions than names).
    odd = joint_state(NAMES, Q[:3], Q, [])
    reader.read_state(serialize_message(first))
    assert reader.read_state(serialize_message(odd))[3] == tuple(Q[:3])


def test_joint_jog_reader():
    """Displacements and velocities of a JointJog, whatever else it carries."""
    msg = JointJog(joint_names=NAMES, velocities=Q, displacements=[0.1] * 6, duration=2.5)
    reader = cdr.JointJogReader()
    for _ in range(2):
        assert reader.read_jog(serialize_message(msg)) == (tuple(NAMES), (0.1,) * 6, tuple(Q))
    bare = JointJog(joint_names=NAMES[:2], velocities=[1.0, 2.0])
    assert reader.read_jog(serialize_message(bare)) == (tuple(NAMES[:2]), (), (1.0, 2.0))


@pytest.mark.parametrize('cut', [0, 3, 4, 11, 30, 120, -12])
def test_reader_refuses_truncated_samples(cut):
    """
    A sample cut short of what is read raises ValueError (the node falls back to rclpy).

    -12: into the last velocity (after it come the effort count and 4 bytes of padding).
    """
    raw = serialize_message(joint_state(NAMES, Q, Q, []))
    with pytest.raises(ValueError):
        cdr.JointStateReader().read_state(raw[:cut])
    reader = cdr.JointStateReader()
    reader.read_state(raw)
    with pytest.raises(ValueError):
        reader.read_state(raw[:cut])


def test_reader_refuses_other_encodings():
    """Only plain CDR (little or big endian) is read; the rest raises ValueError."""
    raw = serialize_message(joint_state(NAMES, Q, Q, []))
    for header in (b'\x00\x02\x00\x00', b'\x00\x03\x00\x00', b'\x01\x01\x00\x00'):
        with pytest.raises(ValueError):
            cdr.JointStateReader().read_state(header + raw[4:])


def test_reader_reads_big_endian():
    """A big-endian sample (another machine's) is read as such."""
    import struct
    body = bytearray()

    def pad(size):
        body.extend(bytes(-len(body) % size))

    body += struct.pack('>iI', 5, 6) + struct.pack('>I', 1) + b'\x00'
    pad(4)
    body += struct.pack('>I', 2)
    for name in (b'a', b'b'):
        pad(4)
        body += struct.pack('>I', len(name) + 1) + name + b'\x00'
    for values in ((1.0, 2.0), (3.0, 4.0), ()):
        pad(4)
        body += struct.pack('>I', len(values))
        if values:
            pad(8)
            body += struct.pack(f'>{len(values)}d', *values)
    raw = b'\x00\x00\x00\x00' + bytes(body)
    expected = joint_state(['a', 'b'], [1.0, 2.0], [3.0, 4.0], [], 5, 6)
    assert deserialize_message(raw, JointState) == expected
    assert cdr.JointStateReader().read_state(raw) == (5, 6, ('a', 'b'), (1.0, 2.0), (3.0, 4.0))
