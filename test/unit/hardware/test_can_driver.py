"""
The package's arm driver against the CAN-level Mover6, in one process over a ``virtual`` bus.

Both are the real classes (``hardware.driver.ArmDriver``, ``sim_bridge.can_arm.CanArm`` with
the MuJoCo arm behind it); time is synthetic and shared: each driver cycle at ``t`` is followed
by the modules answering what arrived by then, so every run is the same.
"""

import itertools

import can
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import load_joints
from mover6_control.parameters import DRIVER
import numpy as np
import pytest
from sim_bridge.can_arm import ModuleTiming
from sim_bridge.can_sim import build_arm, BusServer

CYCLE = 0.05
SILENT_CYCLES = DRIVER['silent_cycles'].default     # the shipped parameter
CHANNELS = itertools.count()
_, JOINTS = load_joints()
TICK = np.array([j.tick for j in JOINTS])


class Rig:
    """The driver and the arm on one virtual bus, stepped together on synthetic time."""

    def __init__(self, home_q=None):
        channel = f'can_driver_test_{next(CHANNELS)}'
        self.t = 0.0
        self.arm = build_arm(home_q=home_q)
        self.arm_bus = can.Bus(interface='virtual', channel=channel)
        self.driver_bus = can.Bus(interface='virtual', channel=channel)
        self.server = BusServer(self.arm, self.arm_bus, clock=lambda: self.t)
        self.driver = ArmDriver(self.driver_bus, JOINTS, clock=lambda: self.t,
                                silent_cycles=SILENT_CYCLES)

    def run(self, duration, velocity=None):
        """Run driver cycles for ``duration`` [s], commanding ``velocity`` (6,) each cycle."""
        report = None
        for _ in range(int(round(duration / CYCLE))):
            if velocity is not None:
                self.driver.set_velocity(velocity, self.t)
            report = self.driver.step(self.t)
            for _ in range(10):       # the frames go frame_gap apart, the modules answer
                self.t += CYCLE / 10
                self.driver.send_due(self.t)
                self.server.poll(0.0)
        return report

    def request(self, kind, joints=None):
        """Make a request and run until it is answered; return (ok, reason)."""
        req = self.driver.request(kind, joints)
        for _ in range(100):
            if req.ok is not None:
                return req.ok, req.reason
            self.run(CYCLE)
        return req.wait(0.0)

    def close(self):
        """Shut both buses."""
        self.driver_bus.shutdown()
        self.arm_bus.shutdown()


@pytest.fixture
def rig():
    """Return a powered-up rig, not enabled."""
    r = Rig()
    yield r
    r.close()


def enabled(rig):
    """Reset, enable and reference what has not been (as the driver's activation); report."""
    ok, reason = rig.request('reset')
    assert ok, reason
    ok, reason = rig.request('enable')
    assert ok, reason
    report = rig.run(CYCLE)
    for n, (j, scale) in enumerate(zip(report.joints, JOINTS), start=1):
        if scale.reference_required and (not j.referenced or j.reference_lost):
            ok, reason = rig.request('reference', [n])
            assert ok, reason
    return rig.run(2 * CYCLE)


def test_start_up_sequence(rig):
    report = rig.run(3 * CYCLE)
    assert report.state == 'error' and report.hold                       # 0x1C at power-up
    assert [j.flags for j in report.joints] == [0x1C] * 6
    ok, reason = rig.request('reset')
    assert ok, reason
    assert rig.run(CYCLE).state == 'connected'
    ok, reason = rig.request('enable')
    assert ok, reason
    report = rig.run(CYCLE)
    assert report.state == 'enabled' and 'joint1: not referenced' in report.hold
    report = enabled(rig)                 # J1..J4 referenced (the joint file's order)
    assert report.state == 'enabled' and report.hold == ''
    assert [j.flags for j in report.joints] == [0] * 6


def test_a_velocity_moves_the_arm_and_it_stops_on_timeout(rig):
    enabled(rig)
    v = np.array([0.2, -0.1, 0.1, 0.3, 0.4, -0.5])
    report = rig.run(1.0, v)
    q_moving = rig.arm.sim.q.copy()
    np.testing.assert_allclose(q_moving, v * 1.0, atol=0.06)
    report = rig.run(1.0)                     # no more commands: the driver's timeout holds it
    assert report.state == 'enabled' and all(j.flags == 0 for j in report.joints)
    q_rest = rig.arm.sim.q.copy()
    assert np.all(np.abs(q_rest - q_moving) <= np.abs(v) * 0.25 + 0.02)   # timeout + a cycle
    rig.run(0.5)
    report = rig.run(CYCLE)
    # At rest: the driver's reading is the arm's, within one tick of each joint.
    measured = np.array([j.q for j in report.joints])
    assert np.all(np.abs(measured - rig.arm.sim.q) <= TICK), (measured - rig.arm.sim.q) / TICK


def test_an_injected_position_lag_holds_the_arm_until_reset_and_enable(rig):
    enabled(rig)
    rig.arm.inject_flags(2, 0x10, rig.t)
    # Three cycles: the hold starts at the cycle that reads the flag, and the set-points sent
    # before it (the last of them frame_gap x 5 into its cycle) take a cycle to be reached.
    report = rig.run(3 * CYCLE, [0.3] * 6)
    assert report.state == 'error' and report.hold
    assert 'position_lag' in report.joints[1].flag_names
    q = rig.arm.sim.q.copy()
    rig.run(0.5, [0.3] * 6)
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)             # the arm holds, to a tick
    enabled(rig)
    rig.run(0.5, [0.3] * 6)
    assert np.all(rig.arm.sim.q - q > 0.05)                          # and moves again


def test_a_silent_module_faults_the_arm_until_reset(rig):
    enabled(rig)
    rig.arm.set_silent(5, True)
    report = rig.run(2 * CYCLE, [0.2] * 6)            # a missed reply: the arm holds at once
    assert report.state == 'enabled' and 'joint5' in report.hold and 'missed' in report.hold
    report = rig.run((SILENT_CYCLES + 1) * CYCLE, [0.2] * 6)
    assert report.state == 'fault' and report.joints[4].state == 'fault'
    q = rig.arm.sim.q.copy()
    rig.run(0.5, [0.2] * 6)
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)
    rig.arm.set_silent(5, False)
    enabled(rig)
    assert rig.run(CYCLE).state == 'enabled'


def test_modules_trip_their_watchdog_when_the_driver_stops(rig):
    enabled(rig)
    for _ in range(int(0.5 / 0.01)):                 # the driver stops cycling
        rig.t += 0.01
        rig.server.poll(0.0)
    assert [m.flags for m in rig.arm.modules] == [0x0C] * 6
    report = rig.run(2 * CYCLE)
    assert report.state == 'error' and 'comm_watchdog' in report.joints[0].flag_names


def test_referencing_one_joint(rig):
    enabled(rig)
    ok, reason = rig.request('reference', [3])
    assert ok, reason
    report = rig.run(CYCLE)
    assert [j.referenced for j in report.joints] == [True] * 4 + [False] * 2
    assert report.joints[2].state == 'referenced'


def held_up(rig, seconds):
    """Hold the driver's control thread up for ``seconds``: the modules run on, get nothing."""
    rig.t += seconds
    rig.server.poll(0.0)


def start_referencing_j1(rig):
    """Reset, enable, ask J1 to reference (the node's timeout); run until its module drives."""
    for kind in ('reset', 'enable'):
        ok, reason = rig.request(kind)
        assert ok, reason
    req = rig.driver.request('reference', [1], timeout=60.0)
    while not rig.arm.modules[0].status()['referencing']:
        rig.run(CYCLE)
    return req


def test_a_module_that_stops_while_referencing_refuses_it_at_once():
    """
    The driver held up past the modules' watchdog while J1 drives to its switch: refused now.

    Before, the request waited out its whole timeout (the node's 60 s) for a referenced bit
    that a stopped module never sets, and said only 'not referenced yet'.
    """
    rig = Rig(home_q=[0.3, 0.0, 0.0, 0.0, 0.0, 0.0])     # 1.5 s to the switch
    try:
        req = start_referencing_j1(rig)
        held_up(rig, rig.arm.timing.watchdog_timeout + CYCLE)
        assert not rig.arm.modules[0].referenced
        start = rig.t
        while req.ok is None and rig.t - start < 1.0:
            rig.run(CYCLE)
        assert req.ok is False, req.reason
        assert 'joint1: module stopped while referencing (comm_watchdog' in req.reason, \
            req.reason
        assert rig.t - start <= 2 * CYCLE + 1e-9
    finally:
        rig.close()


def test_a_referenced_bit_in_a_reply_that_says_the_module_stopped_confirms_nothing(rig):
    """
    J1's module sets its referenced bit, then trips its watchdog, before the driver reads it.

    Before, the referenced bit alone confirmed the referencing; the next joint's was then refused
    with 'the joint must be enabled first' (the activation's failure in the node tests).
    """
    req = start_referencing_j1(rig)                       # at its switch: 0.5 s to the bit
    held_up(rig, rig.arm.timing.watchdog_timeout + CYCLE)
    assert rig.arm.modules[0].referenced and rig.arm.modules[0].flags & 0x08
    rig.run(2 * CYCLE)
    assert req.ok is False, req.reason
    assert 'joint1: module stopped while referencing (comm_watchdog' in req.reason, req.reason


def test_a_brown_out_on_every_module_reads_as_power_lost_with_the_recovery_steps(rig):
    enabled(rig)
    rig.arm.inject_flags(3, 0x01, rig.t)                  # one module: an ordinary error
    report = rig.run(2 * CYCLE)
    assert report.state == 'error' and 'brown_out' in report.hold
    for n in range(1, 7):                                 # all six at once: the e-stop
        rig.arm.inject_flags(n, 0x01, rig.t)
    report = rig.run(2 * CYCLE, [0.2] * 6)
    assert report.state == 'power_lost'
    assert report.hold.startswith('power lost (e-stop?)') and '~/recover' in report.hold
    q = rig.arm.sim.q.copy()
    rig.run(0.5, [0.2] * 6)
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)      # held
    # The modules restarted: J1..J4 lost their reference, latched until re-referenced.
    assert [j.reference_lost for j in report.joints] == [True] * 4 + [False] * 2
    for kind in ('reset', 'enable'):
        ok, reason = rig.request(kind)
        assert ok, reason
    report = rig.run(CYCLE, [0.2] * 6)
    assert 'joint1: reference lost' in report.hold
    enabled(rig)                                          # re-referenced: released
    report = rig.run(CYCLE)
    assert report.state == 'enabled' and report.hold == ''
    assert not any(j.reference_lost for j in report.joints)


def test_no_motion_while_a_required_joint_is_unreferenced(rig):
    """Enabled, J1..J4 not referenced: a command moves nothing, with the reason."""
    for kind in ('reset', 'enable'):
        ok, reason = rig.request(kind)
        assert ok, reason
    q = rig.arm.sim.q.copy()
    report = rig.run(0.5, [0.2] * 6)
    assert report.state == 'enabled' and 'joint1: not referenced' in report.hold
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)
    rig.run(0.3)                                          # the command times out
    for n in (1, 2, 3):                                   # J4 still not referenced
        assert rig.request('reference', [n])[0]
    report = rig.run(0.5, [0.2] * 6)
    assert 'joint4: not referenced' in report.hold
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)
    rig.run(0.3)
    assert rig.request('reference', [4])[0]
    rig.run(0.5, [0.2] * 6)
    assert np.all(rig.arm.sim.q - q > 0.05)               # J5, J6 need none: all six move


def test_referencing_drives_to_the_switch_at_the_referencing_speed():
    """From 0.3 rad, J2 drives to its switch (angle 0) at the referencing speed, then is done."""
    start = 0.3
    rig = Rig(home_q=[0.0, start, 0.0, 0.0, 0.0, 0.0])
    try:
        enabled_without = [rig.request(kind) for kind in ('reset', 'enable')]
        assert all(ok for ok, _ in enabled_without), enabled_without
        timing = ModuleTiming()
        req = rig.driver.request('reference', [2], timeout=10.0)
        t0, path = rig.t, []
        while req.ok is None:
            rig.run(CYCLE)
            path.append((rig.t - t0, rig.arm.sim.q[1]))
        took = rig.t - t0
        assert req.ok, req.reason
        expected = start / timing.reference_speed + timing.reference_time
        print(f'J2 referenced from {start} rad in {took:.3f} s (expected {expected:.3f} s: '
              f'{start} rad at {timing.reference_speed} rad/s, {timing.reference_time} s at the '
              'switch)')
        assert abs(took - expected) <= 3 * CYCLE, (took, expected)
        times, q = np.array(path).T
        moving = (times > 0.2) & (times < start / timing.reference_speed - 0.2)
        speed = np.abs(np.diff(q[moving]) / np.diff(times[moving]))
        assert np.all(np.abs(speed - timing.reference_speed) <= 0.1 * timing.reference_speed), \
            speed
        assert abs(rig.arm.sim.q[1]) <= 2 * TICK[1]
        report = rig.run(CYCLE)
        assert report.joints[1].referenced and abs(report.joints[1].q) <= 2 * TICK[1]
    finally:
        rig.close()


def test_a_dropped_referenced_bit_latches_until_the_joint_is_referenced_again(rig):
    enabled(rig)
    rig.arm.inject_flags(2, 0x01, rig.t)                  # J2's module restarts alone
    report = rig.run(2 * CYCLE)
    assert report.joints[1].reference_lost and not report.joints[1].referenced
    for kind in ('reset', 'enable'):                      # a reset does not clear it
        ok, reason = rig.request(kind)
        assert ok, reason
    q = rig.arm.sim.q.copy()
    report = rig.run(0.5, [0.2] * 6)
    assert report.joints[1].reference_lost and 'joint2: reference lost' in report.hold
    assert np.all(np.abs(rig.arm.sim.q - q) <= TICK)
    rig.run(0.3)                                          # the command times out
    assert rig.request('reference', [2])[0]
    report = rig.run(CYCLE)
    assert not report.joints[1].reference_lost and report.hold == ''
