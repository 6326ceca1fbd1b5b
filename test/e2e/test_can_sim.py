"""
The CAN-level Mover6 as its own process on a pty.

In-process on a virtual bus: the unit test test/unit/sim_bridge/test_can_sim_bus.py.

As a process (``can_sim``) it speaks the CPR USB2CAN framing on a pty, reached through the
package's own ``Usb2CanBus`` exactly as the driver reaches the real adapter.
"""

import os

from can_frames import replies_of, send_all, setpoint_all
from mover6_control.hardware import protocol
from mover6_control.hardware.bus import open_bus
import pytest
from ros_testing import CanSimProcess, wait_until


@pytest.fixture(scope='module')
def can_sim(tmp_path_factory):
    """One can_sim process for this module's tests (it starts slowly on a loaded machine)."""
    folder = tmp_path_factory.mktemp('can_sim')
    with CanSimProcess(folder, folder / 'mover6-can') as sim:
        yield sim


@pytest.fixture
def usb2can(can_sim):
    """Open the package's USB2CAN bus on the simulated arm's pty."""
    bus = open_bus('cpr_usb2can', can_sim.link)
    yield bus
    bus.shutdown()


def test_the_process_answers_through_the_usb2can_framing(can_sim, usb2can):
    assert os.path.realpath(can_sim.link).startswith('/dev/pts/')
    setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], 1)
    got = replies_of(usb2can, 6, 1)
    assert [got[protocol.reply_id(j)].error_flags for j in protocol.JOINTS] == [0x1C] * 6
    send_all(usb2can, protocol.RESET_ERRORS)
    send_all(usb2can, protocol.ENABLE)
    setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], 2)
    got = replies_of(usb2can, 6, 2)
    assert [got[protocol.reply_id(j)].error_flags for j in protocol.JOINTS] == [0x00] * 6
    status = can_sim.control('status')
    assert status['ok'] and [m['flags'] for m in status['modules']] == [0] * 6
    # 12 set-points and 12 commands answered
    assert status['serial_dropped'] == 0 and status['frames_out'] == 24


def test_faults_through_the_control_channel(can_sim, usb2can):
    """An injected position lag on J2 only (the others are as the previous test left them)."""
    assert can_sim.control('flags 2 0x10') == {'ok': True}
    assert can_sim.control('silent 4 on') == {'ok': True}
    setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], 3)
    got = replies_of(usb2can, 5, 3)
    assert protocol.reply_id(4) not in got
    assert got[protocol.reply_id(2)].error_flags & 0x14 == 0x14
    assert got[protocol.reply_id(1)].error_flags & 0x10 == 0
    answer = can_sim.control('flags 9 0x10')
    assert not answer['ok'] and 'joint' in answer['error']
    assert not can_sim.control('warp 3')['ok']
    assert can_sim.control('silent 4 off') == {'ok': True}
    setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], 4)
    assert protocol.reply_id(4) in replies_of(usb2can, 6, 4)
    assert can_sim.alive()


def test_corrupted_bytes_are_dropped_by_the_adapter(can_sim, usb2can):
    """Two corrupted replies of J3: the reader drops both, decodes the rest, then all again."""
    assert can_sim.control('corrupt 2 3') == {'ok': True}
    before = can_sim.control('status')['corrupted']
    for counter in (5, 6):
        setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], counter)
        got = replies_of(usb2can, 5, counter)
        assert protocol.reply_id(3) not in got and len(got) == 5
        assert all(r.position in (0, 500, 509) for r in got.values())
    assert wait_until(lambda: usb2can.dropped == 2, 5.0), usb2can.dropped
    setpoint_all(usb2can, [0, 0, 0, 0, 500, 509], 7)
    got = replies_of(usb2can, 6, 7)
    assert len(got) == 6 and got[protocol.reply_id(3)].position == 0
    status = can_sim.control('status')
    assert status['corrupted'] == before + 2 and status['corrupt_pending'] == 0


def test_the_process_removes_its_link_on_sigint(can_sim):
    """Last in this module: it stops the shared process."""
    assert can_sim.stop() == 0, can_sim.tail()
    assert not os.path.lexists(can_sim.link) and not os.path.exists(can_sim.control_path)
