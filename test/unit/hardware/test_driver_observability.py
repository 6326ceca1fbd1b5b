"""
Observability that cannot move the arm: the driver's frame log and its listen-only mode.

The real classes on python-can's ``virtual`` bus in synthetic time: the CAN-level Mover6
(``CanArm`` behind ``BusServer``), a driver that drives it, and a second driver on the same bus
with ``listen_only``. The frame log is python-can's own writer, read back with python-can's own
reader.
"""

import itertools

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.bus import open_frame_log
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import load_joints
import numpy as np
import pytest
from sim_bridge.can_sim import build_arm, BusServer

_, JOINTS = load_joints()
CYCLE = 0.05
CHANNELS = itertools.count()
HOME = np.array([0.2, -0.1, 0.3, 0.0, 0.2, -0.3])


class Bench:
    """The arm, the driver that drives it and, optionally, a listening driver, on one bus."""

    def __init__(self, frame_log=None, listener=False):
        channel = f'observability_{next(CHANNELS)}'
        self.t = 0.0
        self.arm = build_arm(home_q=HOME)
        self.buses = [can.Bus(interface='virtual', channel=channel) for _ in range(3)]
        self.server = BusServer(self.arm, self.buses[0], clock=lambda: self.t)
        self.driver = ArmDriver(self.buses[1], JOINTS, clock=lambda: self.t,
                                frame_log=frame_log)
        self.listener = ArmDriver(self.buses[2], JOINTS, clock=lambda: self.t,
                                  listen_only=True) if listener else None

    def run(self, duration, velocity=None):
        """Run both drivers' cycles for ``duration`` [s]."""
        for _ in range(int(round(duration / CYCLE))):
            if velocity is not None:
                self.driver.set_velocity(velocity, self.t)
            self.driver.step(self.t)
            if self.listener is not None:
                self.listener.step(self.t)
            for _ in range(10):
                self.t += CYCLE / 10
                self.driver.send_due(self.t)
                self.server.poll(0.0)

    def request(self, kind):
        """Make a request of the driving driver and run until it is answered."""
        req = self.driver.request(kind)
        while req.ok is None:
            self.run(CYCLE)
        return req.wait(0.0)

    def close(self):
        """Close the drivers (the frame log with them) and the arm's bus."""
        self.driver.close()
        if self.listener is not None:
            self.listener.close()
        self.buses[0].shutdown()


def test_the_frame_log_holds_every_frame_both_ways_in_candump_format(tmp_path):
    path = tmp_path / 'frames.log'
    bench = Bench(frame_log=open_frame_log(str(path)))
    assert bench.request('reset')[0] and bench.request('enable')[0]
    bench.run(0.3, [0.1] * 6)
    bench.close()
    text = path.read_text().splitlines()
    assert text and all(line.startswith('(') and line.split()[-1] in ('R', 'T')
                        for line in text), text[:3]
    frames = list(can.LogReader(str(path)))
    sent = [f for f in frames if not f.is_rx]
    read = [f for f in frames if f.is_rx]
    assert {f.arbitration_id for f in sent} == {p.command_id(n) for n in range(1, 7)}
    assert {f.arbitration_id for f in read} == {p.reply_id(n) for n in range(1, 7)}
    kinds = [p.decode_command(bytes(f.data)).kind for f in sent]
    assert kinds[:6] == ['disable'] * 6 and {'reset', 'enable', 'setpoint'} <= set(kinds)
    # Every reply whole: data[5] echoes the counter of a set-point sent to that module.
    counters = {(f.arbitration_id, f.data[6]) for f in sent if f.data[0] == 0x14}
    echoes = [(f.arbitration_id - 1, f.data[5]) for f in read if f.data[5]]
    assert echoes and all(e in counters for e in echoes)
    assert all(len(f.data) == 8 for f in read)


@pytest.mark.parametrize('path, reason', [('/nonexistent-folder/frames.log', 'cannot be written'),
                                          ('frames.unknown_suffix', 'cannot be written'),
                                          ('', 'must be a file path')])
def test_a_frame_log_that_cannot_be_written_is_refused(tmp_path, monkeypatch, path, reason):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InvalidInputError, match=reason):
        open_frame_log(path)


def test_listen_only_sends_nothing_and_reports_what_the_modules_answer():
    bench = Bench(listener=True)
    sent = []
    bench.buses[2].send = lambda msg, timeout=None: sent.append(msg)   # the listener's bus
    bench.run(0.2)
    assert bench.request('reset')[0] and bench.request('enable')[0]
    bench.run(0.5, [0.2, 0, 0, 0, 0, 0])
    report = bench.listener.report
    assert report.hold.startswith('listen_only') and report.frames_bad == 0
    q_listened = np.array([j.q for j in report.joints])
    q_driver = np.array([j.q for j in bench.driver.report.joints])
    assert np.allclose(q_listened, q_driver, atol=0.02)
    assert report.state == 'enabled'
    ok, reason = bench.listener.request('enable').wait(0.0)
    assert not ok and 'listen_only' in reason
    bench.close()
    assert sent == []                        # not a frame, not even the disables at close
