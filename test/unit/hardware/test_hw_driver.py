"""
The arm driver against python-can's ``virtual`` bus and a minimal stand-in for the six modules.

``Modules`` below is a test double used only in this unit test of ``ArmDriver``: it answers each
set-point with a reply as the protocol says (flags 0x1C after power-up, 0x04 after reset, 0x00
after enable; referencing and set zero taking effect on the second frame; the set-point's counter
echoed as the timestamp), answers commands too (timestamp 0) unless told not to, follows a
set-point at once when enabled, and, as the worst firmware may, jumps to the last set-point it
was sent when it is enabled. The cycle runs on synthetic time (``step(t)``), except in the one
test of the control thread.
"""

from dataclasses import replace
import itertools
import threading
import time

import can
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.outbox import Outbox
from mover6_control.hardware.scaling import load_joints
from mover6_control.parameters import DRIVER
import pytest

# The set-point discipline without referencing's hold (the joint file may say a joint needs no
# referencing; test_can_driver.py tests the hold and the referencing).
JOINTS = tuple(replace(j, reference_required=False) for j in load_joints()[1])
SILENT_CYCLES = DRIVER['silent_cycles'].default     # the shipped parameter
CHANNELS = itertools.count()


class Modules:
    """Six module stand-ins on the other end of a virtual bus (test double)."""

    def __init__(self, bus, positions=None, answers_commands=True):
        self.bus = bus
        self.answers_commands = answers_commands
        self.enabled_at = {}     # joint -> (last set-point, position) when it was enabled
        self.gaps = []           # (joint, |set-point - position|) of set-points taken enabled
        self.flags = dict.fromkeys(range(1, 7), 0x1C)
        self.wire = {n: (positions or {}).get(n, 0) + JOINTS[n - 1].offset for n in range(1, 7)}
        self.inputs = dict.fromkeys(range(1, 7), 0)
        self.silent = set()
        self.frozen = set()
        self.log = []            # (joint, Command)
        self.repeats = {}
        self.kept = {}           # joint -> the last set-point it was sent

    def serve(self):
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            joint, is_reply = p.joint_of_id(msg.arbitration_id)
            assert not is_reply
            cmd = p.decode_command(bytes(msg.data))
            self.log.append((joint, cmd))
            self._apply(joint, cmd)

    def _apply(self, n, cmd):
        # Referencing and set zero take effect on the second frame of their kind.
        second = cmd.kind != 'setpoint' and self.repeats.get(n) == cmd.kind
        if cmd.kind != 'setpoint':
            self.repeats[n] = None if second else cmd.kind
        if cmd.kind == 'reset':
            self.flags[n] = 0x04
        elif cmd.kind == 'disable':
            self.flags[n] |= 0x04
        elif cmd.kind == 'enable' and self.flags[n] == 0x04:
            self.flags[n] = 0x00
            self.enabled_at[n] = (self.kept.get(n), self.wire[n])
            if n in self.kept and n not in self.frozen:
                self.wire[n] = self.kept[n]          # drives to the kept set-point
        elif cmd.kind == 'reference' and second:
            self.inputs[n] |= p.REFERENCED
        elif cmd.kind == 'set_zero' and second:
            self.wire[n] = cmd.position
        elif cmd.kind == 'setpoint':
            self.kept[n] = cmd.position
            if self.flags[n] == 0:
                self.gaps.append((n, abs(cmd.position - self.wire[n])))
                if n not in self.frozen:
                    self.wire[n] = cmd.position
        if n not in self.silent and (cmd.kind == 'setpoint' or self.answers_commands):
            stamp = cmd.counter if cmd.kind == 'setpoint' else 0
            self.bus.send(can.Message(arbitration_id=p.reply_id(n), is_extended_id=False,
                                      data=p.encode_reply(self.flags[n], self.wire[n], stamp,
                                                          self.inputs[n])))

    def largest_gap(self):
        """Return the largest |set-point - position| an enabled module met [wire ticks]."""
        gaps = [g for _, g in self.gaps]
        gaps += [abs(kept - wire) for kept, wire in self.enabled_at.values() if kept is not None]
        return max(gaps, default=0)

    def setpoints(self, n):
        return [c.position for j, c in self.log if j == n and c.kind == 'setpoint']


class Rig:
    """A driver, its modules and a synthetic clock."""

    def __init__(self, positions=None, answers_commands=True, **kwargs):
        channel = f'driver_test_{next(CHANNELS)}'
        self.t = 100.0
        self.modules = Modules(can.Bus(interface='virtual', channel=channel), positions,
                               answers_commands)
        self.driver = ArmDriver(can.Bus(interface='virtual', channel=channel), JOINTS,
                                clock=lambda: self.t, **kwargs)

    def run(self, cycles=1):
        for _ in range(cycles):
            self.t += self.driver.cycle
            report = self.driver.step(self.t)
            self.modules.serve()
            for k in range(1, 10):               # the frames go frame_gap apart
                self.driver.send_due(self.t + k * self.driver.cycle / 10)
                self.modules.serve()
        return report

    def until(self, req, cycles=40):
        for _ in range(cycles):
            self.run()
            if req.ok is not None:
                return req.wait(0)
        raise AssertionError(f'{req.kind} got no answer in {cycles} cycles')

    def enable(self):
        assert self.until(self.driver.request('reset'))[0]
        ok, reason = self.until(self.driver.request('enable'))
        assert ok, reason

    def close(self):
        self.driver.close()
        self.modules.bus.shutdown()


@pytest.fixture
def rig():
    made = []

    def make(**kwargs):
        made.append(Rig(**kwargs))
        return made[-1]
    yield make
    for r in made:
        r.close()


def test_start_disables_first_and_then_sets_the_measured_position(rig):
    r = rig(positions={1: 12345, 5: -40})
    report = r.run(3)
    first = r.modules.log[:6]
    assert first == [(n, p.Command('disable')) for n in range(1, 7)]
    # The modules answer the disable with their positions: the first set-point is there.
    assert r.modules.setpoints(1) == [12345, 12345]
    assert r.modules.setpoints(5) == [-40 + 500, -40 + 500]
    # Power-up flags 0x1C: watchdog and position lag on top of "motor not enabled".
    assert report.state == 'error' and 'comm_watchdog, position_lag' in report.hold
    assert report.joints[0].q == pytest.approx(JOINTS[0].to_rad(12345))


def test_enable_then_velocities_become_setpoints(rig):
    r = rig(positions={1: 1000})
    r.enable()
    assert r.driver.report.state == 'enabled' and r.driver.report.hold == ''
    start = r.modules.setpoints(1)[-1]
    assert start == 1000                                    # no jump at enable
    for _ in range(4):
        r.driver.set_velocity([0.1, 0, 0, 0, 0.02, 0])
        r.run()
    sp1, sp5 = r.modules.setpoints(1), r.modules.setpoints(5)
    step = 0.1 * 0.05 * JOINTS[0].ticks_per_rad             # J1's gear > 0: ticks go up
    assert all(abs((b - a) - step) <= 1 for a, b in zip(sp1[-4:], sp1[-3:]))
    assert sp1[-1] > start
    # J5 at 0.02 rad/s is 0.16 ticks per cycle: it still moves, by fractional ticks.
    for _ in range(20):
        r.driver.set_velocity([0.1, 0, 0, 0, 0.02, 0])
        r.run()
    assert r.modules.setpoints(5)[-1] - sp5[-1] >= 2


def test_a_resting_setpoint_is_the_tick_sent_so_whole_tick_moves_stay_whole(rig):
    """J5 moved 0.47 tick, then at rest: a later move of 2.05 ticks sends 2 ticks, not 3."""
    r = rig()
    r.enable()
    tick_rate = JOINTS[4].tick / r.driver.cycle             # [rad/s] one tick per cycle
    start = r.modules.setpoints(5)[-1]
    r.driver.set_velocity([0, 0, 0, 0, 0.47 * tick_rate, 0])
    r.run()
    assert r.modules.setpoints(5)[-1] == start               # 0.47 tick rounds to none
    r.driver.set_velocity([0.0] * 6)
    report = r.run()
    assert report.joints[4].setpoint == JOINTS[4].to_rad(start - JOINTS[4].offset)
    r.driver.set_velocity([0, 0, 0, 0, 2.05 * tick_rate, 0])
    r.run()
    assert r.modules.setpoints(5)[-1] == start + 2
    r.driver.set_velocity([0.0] * 6)
    assert r.run().joints[4].setpoint == JOINTS[4].to_rad(start + 2 - JOINTS[4].offset)


def test_command_timeout_holds_within_one_cycle(rig):
    r = rig()
    r.enable()
    r.driver.set_velocity([0.3] * 6)
    t0 = r.t
    r.run(10)
    sent_after = r.modules.setpoints(3)[-10:]
    moving = [i for i in range(1, 10) if sent_after[i] != sent_after[i - 1]]
    # Commands are fresh for 0.2 s = 4 cycles; at the 5th cycle after t0 the set-point holds.
    assert moving and max(moving) <= 4
    assert r.t - t0 > 0.2
    assert all(j.qd == 0.0 or abs(j.qd) < 1e-9 for j in r.run(2).joints)


def test_setpoints_never_leave_the_hardware_limits(rig):
    lo, hi = JOINTS[1].tick_limits('hardware')
    r = rig(positions={2: lo + 500})
    r.enable()
    for _ in range(30):
        r.driver.set_velocity([0, 0.5, 0, 0, 0, 0])     # J2 gear < 0: towards the lower ticks
        r.run()
    sp = r.modules.setpoints(2)
    assert min(sp) == lo and all(lo <= s <= hi for s in sp)


def test_setpoint_stays_within_max_lag_of_the_measured(rig):
    r = rig(max_lag=0.05)
    r.enable()
    r.modules.frozen.add(6)                                # J6's motor does not follow
    for _ in range(20):
        r.driver.set_velocity([0, 0, 0, 0, 0, 1.5])
        r.run()
    lag_ticks = 0.05 * abs(JOINTS[5].ticks_per_rad)
    assert all(abs(s - 509) <= lag_ticks + 0.5 for s in r.modules.setpoints(6))
    assert r.driver.report.joints[5].lag == pytest.approx(0.05, abs=JOINTS[5].tick)


def test_an_error_flag_holds_the_arm_and_reset_enable_recover(rig):
    r = rig()
    r.enable()
    r.driver.set_velocity([0.2] * 6)
    r.run(2)
    r.modules.flags[3] = 0x10 | 0x04                       # position lag: the module stops
    report = r.run(2)
    assert report.state == 'error' and 'position_lag' in report.hold
    assert report.joints[2].flag_names == ('motor_not_enabled', 'position_lag')
    held = [r.modules.setpoints(n)[-1] for n in range(1, 7)]
    r.driver.set_velocity([0.2] * 6)
    r.run(3)
    assert [r.modules.setpoints(n)[-1] for n in (1, 2, 4, 5, 6)] == \
        [held[i] for i in (0, 1, 3, 4, 5)]
    r.driver.set_velocity([0.0] * 6)
    r.modules.wire[3] += 777                               # it drifted while in error
    r.enable()
    assert r.driver.report.state == 'enabled'
    assert r.modules.setpoints(3)[-1] == r.modules.wire[3]  # restarts where it is


def test_a_missed_reply_holds_and_a_silent_module_faults_after_silent_cycles(rig):
    r = rig(silent_cycles=3)
    r.enable()
    r.driver.set_velocity([0.1] * 6)
    assert r.run().hold == ''
    r.modules.silent.add(4)
    # The reply already on the bus is read first; then three cycles without one: the first
    # missed reply holds the arm (set-points frozen), the third latches the fault.
    reports = []
    for _ in range(5):
        r.driver.set_velocity([0.1] * 6)
        reports.append(r.run())
    states = [rep.joints[3].state for rep in reports]
    assert states == ['enabled'] * 3 + ['fault'] * 2
    assert 'joint4: 1 reply(ies) missed, holds' in reports[1].hold
    frozen = r.modules.setpoints(1)[-4:]
    assert len(set(frozen)) == 1, frozen                         # no motion while blind
    # The silent module (it may still hear) keeps its last set-point through the latch: not
    # a step back to the last position it reported.
    blind = r.modules.setpoints(4)[-4:]
    assert len(set(blind)) == 1, blind
    assert 'joint4: module silent for 4 cycles' in r.driver.report.hold
    r.modules.silent.clear()
    assert r.run(2).state == 'fault'                        # latched until a reset
    # Silent again, and moved on after its last reply; it answers again just as the reset goes.
    r.modules.silent.add(4)
    r.modules.frozen.add(4)
    r.modules.wire[4] += 300
    r.run()
    r.modules.silent.clear()
    since = len(r.modules.log)
    r.enable()
    assert r.driver.report.state == 'enabled'
    # Its last reported position is stale: after the reset it is read again, and every
    # set-point the module takes is where it is.
    recovered = [c.position for j, c in r.modules.log[since:] if j == 4 and c.kind == 'setpoint']
    assert recovered and set(recovered) == {r.modules.wire[4]}, (recovered, r.modules.wire[4])


def test_a_module_lost_during_enable_disables_all_six(rig):
    r = rig()
    assert r.until(r.driver.request('reset'))[0]
    r.modules.silent.add(2)
    ok, reason = r.until(r.driver.request('enable', timeout=0.3))
    assert not ok and 'joint2' in reason and 'all six disabled' in reason
    r.run()                               # the disables go out frame_gap apart
    assert all(r.modules.flags[n] & 0x04 for n in range(1, 7))     # none left enabled


def test_enable_times_out_with_the_reason_and_disables_all_six(rig):
    r = rig()
    assert r.until(r.driver.request('reset'))[0]
    original = r.modules._apply

    def refuse_enable(n, cmd):
        if not (n == 3 and cmd.kind == 'enable'):
            original(n, cmd)
    r.modules._apply = refuse_enable
    ok, reason = r.until(r.driver.request('enable', timeout=0.3))
    assert not ok and 'joint3' in reason and 'not confirmed within 0.3 s' in reason
    assert 'all six disabled' in reason
    r.run()                               # the disables go out frame_gap apart
    assert all(r.modules.flags[n] & 0x04 for n in range(1, 7))


def test_corrupted_reply_is_counted_never_decoded(rig):
    r = rig(positions={1: 50})
    r.run(2)
    r.modules.bus.send(can.Message(arbitration_id=0x11, is_extended_id=False,
                                   data=bytes.fromhex('00 7F FF FF FF 00 00')))
    report = r.run()
    assert report.frames_bad == 1
    assert report.joints[0].q == pytest.approx(JOINTS[0].to_rad(50))


def test_reference_one_joint_twice_and_refusals(rig):
    r = rig()
    ok, reason = r.driver.request('reference', [2]).wait(0)
    assert not ok and 'enabled first' in reason
    r.enable()
    r.driver.set_velocity([0.1] * 6)
    ok, reason = r.driver.request('reference', [2]).wait(0)
    assert not ok and 'moving' in reason
    r.driver.set_velocity([0.0] * 6)
    r.run(6)
    n_before = len(r.modules.log)
    ok, reason = r.until(r.driver.request('reference', [2]))
    assert ok, reason
    refs = [j for j, c in r.modules.log[n_before:] if c.kind == 'reference']
    assert refs == [2, 2]
    assert r.driver.report.joints[1].state == 'referenced'


def test_set_zero_twice_and_the_setpoint_follows(rig):
    r = rig(positions={1: 5000, 2: -300})
    r.enable()
    ok, reason = r.driver.request('set_zero').wait(0)
    assert not ok and 'disable the motors first' in reason
    assert r.until(r.driver.request('disable'))[0]
    n_before = len(r.modules.log)
    ok, reason = r.until(r.driver.request('set_zero'))
    assert ok, reason
    assert [j for j, c in r.modules.log[n_before:] if c.kind == 'set_zero'] == \
        [1, 2, 3, 4, 5, 6] * 2
    assert r.modules.setpoints(1)[-1] == 0 and r.modules.setpoints(2)[-1] == 0
    r.enable()
    assert r.modules.setpoints(1)[-1] == 0 and r.driver.report.hold == ''


def test_bad_velocity_is_refused_and_the_previous_command_stands(rig):
    r = rig()
    r.enable()
    r.driver.set_velocity([0.1] * 6)
    for bad in ([0.1] * 5, [float('nan')] + [0.0] * 5, [float('inf')] * 6):
        with pytest.raises(InvalidInputError):
            r.driver.set_velocity(bad)
    r.run(2)
    assert r.driver.report.joints[0].qd == pytest.approx(0.1, rel=0.05)


def test_outputs_ride_on_the_setpoint(rig):
    r = rig()
    r.driver.set_outputs(4, 0x03)
    r.run(2)
    assert [c.digital_out for j, c in r.modules.log if j == 4 and c.kind == 'setpoint'][-1] == 3
    with pytest.raises(InvalidInputError):
        r.driver.set_outputs(4, 256)


def test_close_disables_every_module():
    channel = f'driver_test_{next(CHANNELS)}'
    modules = Modules(can.Bus(interface='virtual', channel=channel))
    driver = ArmDriver(can.Bus(interface='virtual', channel=channel), JOINTS)
    driver.step(1.0)
    modules.serve()
    modules.log.clear()
    driver.close()
    modules.serve()
    assert modules.log == [(n, p.Command('disable')) for n in range(1, 7)]
    modules.bus.shutdown()


def test_the_control_thread_runs_the_cycle_on_the_real_clock():
    channel = f'driver_test_{next(CHANNELS)}'
    modules = Modules(can.Bus(interface='virtual', channel=channel))
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            modules.serve()
            time.sleep(0.002)
    server = threading.Thread(target=serve, daemon=True)
    server.start()
    driver = ArmDriver(can.Bus(interface='virtual', channel=channel), JOINTS)
    driver.start()
    try:
        assert driver.request('reset').wait(30.0)[0]
        ok, reason = driver.request('enable').wait(30.0)
        assert ok, reason
        deadline = time.monotonic() + 30.0
        while driver.report.state != 'enabled' and time.monotonic() < deadline:
            time.sleep(0.01)
        assert driver.report.state == 'enabled'
    finally:
        driver.close()
        stop.set()
        server.join()
        modules.bus.shutdown()


def send_raw(r, **kwargs):
    """Put one frame on the bus as a foreign sender (another node, a broken adapter)."""
    r.modules.bus.send(can.Message(**kwargs))


def test_foreign_and_malformed_frames_are_dropped_by_reason(rig):
    r = rig(positions={1: 50})
    r.enable()
    good = p.encode_reply(0x00, 50, 0, 0)
    send_raw(r, arbitration_id=0x7F1, is_extended_id=False, data=good)        # unknown ID
    send_raw(r, arbitration_id=0x71, is_extended_id=False, data=good)         # module 7
    send_raw(r, arbitration_id=0x11, is_extended_id=True, data=good)          # extended
    send_raw(r, arbitration_id=0x11, is_extended_id=False, is_remote_frame=True, dlc=8)
    send_raw(r, arbitration_id=0x11, is_extended_id=False, data=good[:5])     # DLC 5
    send_raw(r, arbitration_id=0x10, is_extended_id=False,                    # another master
             data=p.encode_setpoint(99999, 0, 0))
    report = r.run()
    assert dict(report.bad_frames) == {'unknown_id': 2, 'extended_id': 1, 'wrong_length': 1,
                                       'remote_or_error_frame': 1,
                                       'command_of_another_master': 1}
    assert report.frames_bad == 6
    assert 'command_of_another_master: id 0x10 dlc 8' in report.last_bad_frame
    assert report.state == 'enabled' and report.hold == ''
    assert report.joints[0].q == pytest.approx(JOINTS[0].to_rad(50))
    assert r.modules.setpoints(1)[-1] == 50                 # nothing moved


def test_a_reply_that_jumps_is_dropped_and_the_setpoint_never_follows(rig):
    r = rig(positions={2: 1000})
    r.enable()
    jump = 1000 + int(0.5 * abs(JOINTS[1].ticks_per_rad))           # 0.5 rad in one cycle
    for _ in range(2):
        send_raw(r, arbitration_id=p.reply_id(2), is_extended_id=False,
                 data=p.encode_reply(0x00, jump, 0, 0))
        report = r.run()
        assert report.joints[1].q == pytest.approx(JOINTS[1].to_rad(1000))
    assert dict(report.bad_frames) == {'position_jump': 2}
    assert set(r.modules.setpoints(2)[-4:]) == {1000}
    # A module whose every reply jumps: no valid reply, so it goes silent and the arm holds.
    r.modules.frozen.add(2)
    r.modules.wire[2] = jump
    states = [r.run().joints[1].state for _ in range(SILENT_CYCLES + 2)]
    assert states[-1] == 'fault' and r.driver.report.hold
    assert set(r.modules.setpoints(2)) == {1000}          # none before the first reply either
    r.enable()                                                # reset: the new position stands
    assert r.driver.report.state == 'enabled'
    assert r.modules.setpoints(2)[-1] == jump


def test_a_plausible_wrong_position_never_moves_a_setpoint_more_than_the_command(rig):
    """
    Serial bytes that pass the checksum but carry a wrong position within reach.

    The plausibility check cannot tell them (``max_lag`` plus twice the top speed over a cycle);
    the set-point still moves only by the commanded step and stays within the limits.
    """
    lo, hi = JOINTS[2].tick_limits('hardware')
    r = rig(positions={3: hi - 3000})
    r.enable()
    v = [0, 0, 0.1, 0, 0, 0]
    step = 0.1 * r.driver.cycle * abs(JOINTS[2].ticks_per_rad) + 1
    wrong = int(0.15 * abs(JOINTS[2].ticks_per_rad))             # 0.15 rad: within reach
    for k in range(12):
        if k % 3 == 1:
            send_raw(r, arbitration_id=p.reply_id(3), is_extended_id=False,
                     data=p.encode_reply(0x00, r.modules.wire[3] + (-1) ** k * wrong, 0, 0))
        r.driver.set_velocity(v)
        r.run()
    sp = r.modules.setpoints(3)
    assert dict(r.driver.report.bad_frames).get('position_jump', 0) == 0    # all taken
    assert max(abs(b - a) for a, b in zip(sp, sp[1:])) <= step
    assert all(lo <= s <= hi for s in sp) and max(sp) == hi              # and up to the limit


def test_the_control_thread_reports_its_scheduling():
    channel = f'driver_test_{next(CHANNELS)}'
    driver = ArmDriver(can.Bus(interface='virtual', channel=channel), JOINTS)
    assert driver.scheduling == 'not started'
    driver.start()
    try:
        deadline = time.monotonic() + 30.0
        while driver.report is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert driver.scheduling == 'normal scheduling (priority 0)'
    finally:
        driver.close()


def test_the_driver_on_a_pty_drops_what_the_wire_and_the_bus_bring_wrong():
    """Hand-written serial bytes: truncated, garbage, wrong DLC, unknown ID, then good replies."""
    import fcntl
    import os
    from mover6_control.hardware.usb2can import encode_serial_frame, Usb2CanBus
    master, slave = os.openpty()
    fcntl.fcntl(master, fcntl.F_SETFL, fcntl.fcntl(master, fcntl.F_GETFL) | os.O_NONBLOCK)
    driver = ArmDriver(Usb2CanBus(os.ttyname(slave)), JOINTS)
    try:
        good = [encode_serial_frame(p.reply_id(n), p.encode_reply(0x1C, 50 + n, 0, 0))
                for n in range(1, 7)]
        wire = (good[0][:6] + b'\xff\x00\x13'                       # cut short, garbage
                + encode_serial_frame(0x11, p.encode_reply(0x1C, 9999, 0, 0)[:5])   # DLC 5
                + encode_serial_frame(0x7F, p.encode_reply(0x1C, 9999, 0, 0))       # no module
                + b''.join(good))
        os.write(master, wire)
        t, report = 100.0, None
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            t += driver.cycle
            report = driver.step(t)
            try:
                os.read(master, 4096)                     # the set-points: nobody needs them
            except BlockingIOError:
                pass
            if all(j.replies for j in report.joints):
                break
            time.sleep(0.01)
        assert all(j.replies == 1 for j in report.joints), report
        assert report.frames_dropped >= 1                 # the serial reader's
        assert dict(report.bad_frames) == {'wrong_length': 1, 'unknown_id': 1}
        assert [JOINTS[i].to_ticks(j.q) for i, j in enumerate(report.joints)] == \
            [JOINTS[i].from_wire(51 + i) for i in range(6)]
    finally:
        driver.close()
        os.close(slave)
        os.close(master)


def test_a_reply_whose_timestamp_did_not_move_is_refused_and_the_joint_goes_silent(rig):
    """The vendor's Joint.cpp ignores such a reply; here it is refused, counted, and held."""
    r = rig(positions={2: 700})
    r.enable()
    original = r.modules._apply
    stuck = {}

    def stale(n, cmd):
        if n == 2 and cmd.kind == 'setpoint':      # answers every set-point with one old reply
            if 'frame' not in stuck:
                stuck['frame'] = p.encode_reply(0, r.modules.wire[2] + 50, cmd.counter, 0)
            r.modules.bus.send(can.Message(arbitration_id=p.reply_id(2), is_extended_id=False,
                                           data=stuck['frame']))
            return
        original(n, cmd)
    r.modules._apply = stale
    report = r.run(SILENT_CYCLES + 3)
    assert dict(report.bad_frames).get('stale_timestamp', 0) >= 3
    assert report.hold and 'joint2' in report.hold and report.state == 'fault'


def test_the_outbox_keeps_the_order_and_the_gap():
    channel = f'outbox_{next(CHANNELS)}'
    tx, rx = (can.Bus(interface='virtual', channel=channel) for _ in range(2))
    try:
        box = Outbox(tx, 0.005)
        seqs = [box.put(0x10, b'\x01\x0a', 10.0), box.put(0x20, b'\x01\x0a', 10.0),
                box.put(0x30, b'\x01\x09', 10.0, not_before=10.02),
                box.put(0x40, b'\x01\x0a', 10.0)]
        assert seqs == sorted(seqs) and len(box) == 4
        assert box.send_due(10.0) == 1                   # the gap: one frame now
        assert box.next_due() == pytest.approx(10.005)
        assert box.send_due(10.005) == 1
        assert box.send_due(10.015) == 0                 # the third waits for its time...
        assert box.send_due(10.02) == 1
        assert box.send_due(10.025) == 1                 # ...and the fourth behind it
        ids = [rx.recv(1.0).arbitration_id for _ in range(4)]
        assert ids == [0x10, 0x20, 0x30, 0x40]
        assert box.sent_at[0x40] == 10.025 and box.next_due() is None
        # A thread that wakes late sends every frame whose plan passed: it catches up.
        for k in range(6):
            box.put(0x10 * (k + 1), b'\x01\x0a', 10.1)
        assert box.send_due(10.118) == 4 and box.send_due(10.2) == 2
    finally:
        tx.shutdown()
        rx.shutdown()
