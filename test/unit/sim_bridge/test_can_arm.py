"""
The CAN-level Mover6: its modules answer frame by frame as the real ones, in synthetic time.

Frames are built with ``mover6_control.hardware.protocol`` (checked byte for byte against the
vendor's sources in its own tests); the arm behind the modules is the real MuJoCo simulator.
Times are synthetic [s]: ``CanArm`` runs the physics at real time from the first call.
"""

import math

from mover6_control.hardware import protocol
import numpy as np
import pytest
from sim_bridge.can_arm import ModuleTiming, NOT_ENABLED, POSITION_LAG, POWER_UP_FLAGS, WATCHDOG
from sim_bridge.can_sim import build_arm

CYCLE = 0.05


@pytest.fixture
def arm():
    """Return a freshly powered-up arm at q = 0."""
    return build_arm()


def send(arm, joint, data, t):
    """Send one frame to ``joint``'s module at ``t``; return the decoded replies."""
    out = arm.receive(protocol.command_id(joint), data, t)
    for can_id, _ in out:
        assert can_id == protocol.reply_id(joint)
    return [protocol.decode_reply(d) for _, d in out]


def setpoints(arm, ticks, t, counter=0):
    """Send a set-point to every module at ``t``; return the six replies."""
    replies = []
    for joint, p in zip(protocol.JOINTS, ticks):
        got = send(arm, joint, protocol.encode_setpoint(int(p), counter), t)
        assert len(got) == 1
        replies.append(got[0])
    return replies


def command_all(arm, data, t):
    """Send the same command to every module at ``t``; return the replies (timestamp 0)."""
    replies = []
    for joint in protocol.JOINTS:
        got = send(arm, joint, data, t)
        expected = 1 if arm.modules[joint - 1].answers_commands else 0
        assert len(got) == expected and all(r.timestamp == 0 for r in got)
        replies += got
    return replies


def enable(arm, t):
    """Reset and enable every module at ``t`` with set-points at the present position."""
    setpoints(arm, arm.positions(), t)
    command_all(arm, protocol.RESET_ERRORS, t)
    command_all(arm, protocol.ENABLE, t + 0.001)
    return [r.error_flags for r in setpoints(arm, arm.positions(), t + 0.002)]


def test_power_up_reset_enable_flags(arm):
    replies = setpoints(arm, arm.positions(), 0.0)
    assert [r.error_flags for r in replies] == [POWER_UP_FLAGS] * 6 == [0x1C] * 6
    # At q = 0 the encoders read the joints' offsets (J5 500, J6 509, the vendor's).
    assert [r.position for r in replies] == [s.offset for s in arm.scales]
    assert [s.offset for s in arm.scales][4:] == [500, 509]
    assert not any(r.referenced for r in replies)
    command_all(arm, protocol.ENABLE, 0.01)               # no reset first: refused
    assert [r.error_flags for r in setpoints(arm, arm.positions(), 0.02)] == [0x1C] * 6
    command_all(arm, protocol.RESET_ERRORS, 0.03)
    assert [r.error_flags for r in setpoints(arm, arm.positions(), 0.04)] == [0x04] * 6
    command_all(arm, protocol.ENABLE, 0.05)
    assert [r.error_flags for r in setpoints(arm, arm.positions(), 0.06)] == [0x00] * 6
    command_all(arm, protocol.DISABLE, 0.07)
    assert [r.error_flags for r in setpoints(arm, arm.positions(), 0.08)] == [0x04] * 6


def test_a_reply_echoes_the_set_point_counter_and_a_command_answers_with_0(arm):
    assert [r.timestamp for r in setpoints(arm, arm.positions(), 0.0, counter=17)] == [17] * 6
    assert [r.timestamp for r in setpoints(arm, arm.positions(), 0.05, counter=18)] == [18] * 6
    replies = command_all(arm, protocol.DISABLE, 0.06)
    assert [r.timestamp for r in replies] == [0] * 6
    assert [r.position for r in replies] == arm.positions().tolist()


def test_modules_that_answer_only_set_points():
    arm = build_arm(answers_commands=False)
    for data in (protocol.RESET_ERRORS, protocol.DISABLE, protocol.ENABLE):
        assert command_all(arm, data, 0.0) == []
    assert len(setpoints(arm, arm.positions(), 0.01, counter=3)) == 6


def test_a_disabled_module_keeps_its_last_set_point_and_drives_there_on_enable(arm):
    """The worst a firmware may do: the reason a driver primes the set-point before enable."""
    far = arm.positions().copy()
    far[0] += 2000                                 # ~1 deg of J1
    setpoints(arm, far, 0.0, counter=1)            # disabled: nothing moves
    command_all(arm, protocol.RESET_ERRORS, 0.01)
    arm.advance(0.3)
    assert arm.positions()[0] == far[0] - 2000
    assert arm.modules[0].max_setpoint_gap == 0
    command_all(arm, protocol.ENABLE, 0.31)        # no set-point since: it drives to the kept one
    arm.advance(1.5)
    assert abs(arm.positions()[0] - far[0]) <= 2
    assert arm.modules[0].max_setpoint_gap == 2000


def test_set_zero_takes_the_value_in_its_last_two_bytes(arm):
    for joint, value in ((1, 0), (5, 500), (6, 509), (2, 0x7D00)):
        send(arm, joint, protocol.encode_set_zero(value), 0.0)
        send(arm, joint, protocol.encode_set_zero(value), 0.02)
        assert arm.positions()[joint - 1] == value


@pytest.mark.parametrize('data', [
    protocol.RESET_ERRORS + bytes(6),         # the right command padded to DLC 8
    protocol.RESET_ERRORS[:1],                # cut short
    protocol.SET_ZERO[:2],                    # set zero with DLC 2
    protocol.encode_setpoint(0, 0)[:7],       # a set-point with DLC 7
    b'\x01\x77',                              # no such command
])
def test_a_frame_of_the_wrong_length_is_ignored(arm, data):
    before = arm.modules[0].status()
    assert send(arm, 1, data, 0.0) == []
    after = arm.modules[0].status()
    assert after['ignored'] == before['ignored'] + 1
    assert after['flags'] == before['flags'] == POWER_UP_FLAGS
    assert after['setpoints'] == before['setpoints']


def test_reset_of_the_wrong_length_does_not_reset(arm):
    setpoints(arm, arm.positions(), 0.0)
    send(arm, 3, protocol.RESET_ERRORS + bytes(6), 0.01)
    assert setpoints(arm, arm.positions(), 0.02)[2].error_flags == POWER_UP_FLAGS


def test_frames_on_other_ids_are_not_answered(arm):
    assert arm.receive(protocol.reply_id(2), protocol.encode_setpoint(0, 0), 0.0) == []
    assert arm.receive(0x75, protocol.encode_setpoint(0, 0), 0.0) == []
    assert arm.foreign == 2


def test_the_arm_follows_set_points_within_its_speed_limit(arm):
    """J1 at 0.4 rad/s and J6 at 1.5 rad/s for 1 s: the physics follows, no faster than allowed."""
    assert enable(arm, 0.0) == [0] * 6
    t, q_sp = 0.05, np.zeros(6)
    v = np.array([0.4, 0.0, 0.0, 0.0, 0.0, 1.5])
    vmax = np.array(arm.arm.velocity_limits)
    peak = np.zeros(6)
    for k in range(20):
        q_sp = q_sp + v * CYCLE
        replies = setpoints(arm, arm.ticks_of(q_sp), t, k)
        assert [r.error_flags for r in replies] == [0] * 6
        for _ in range(5):
            t += CYCLE / 5
            arm.advance(t)
            peak = np.maximum(peak, np.abs(arm.sim.qd))
        assert np.all(np.abs(arm.sim.q - q_sp) < 0.05)         # follows within a cycle's step
    assert np.all(peak <= vmax * (1 + 1e-6) + 1e-9), (peak, vmax)
    assert peak[0] > 0.3 and peak[5] > 1.2
    for _ in range(20):                                     # hold the last set-point 1 s
        replies = setpoints(arm, arm.ticks_of(q_sp), t)
        t += CYCLE
        arm.advance(t)
    replies = setpoints(arm, arm.ticks_of(q_sp), t)
    # Settled: every encoder within one tick of its set-point, and the reply says so.
    np.testing.assert_allclose([r.position for r in replies], arm.ticks_of(q_sp), atol=1)
    tick = 1.0 / np.abs([s.ticks_per_rad for s in arm.scales])
    assert np.all(np.abs(arm.sim.q - q_sp) <= tick), (arm.sim.q - q_sp) / tick


def test_a_set_point_jump_raises_position_lag(arm):
    enable(arm, 0.0)
    q_sp = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])           # 0.3 rad in one frame
    setpoints(arm, arm.ticks_of(q_sp), 0.05)
    t = 0.05
    while t < 0.2:
        t += 0.01
        arm.advance(t)
    flags = [r.error_flags for r in setpoints(arm, arm.ticks_of(q_sp), t)]
    assert flags[1] == POSITION_LAG | NOT_ENABLED
    assert flags[:1] + flags[2:] == [0] * 5
    assert abs(arm.sim.q[1]) < 0.3 - ModuleTiming().lag_limit + 0.02     # it stopped


def test_a_step_within_the_lag_limit_is_followed(arm):
    enable(arm, 0.0)
    q_sp = np.array([0.0, 0.02, 0.0, 0.0, 0.0, 0.0])
    t = 0.05
    for _ in range(10):
        flags = [r.error_flags for r in setpoints(arm, arm.ticks_of(q_sp), t)]
        assert flags == [0] * 6
        t += CYCLE
        arm.advance(t)
    assert abs(arm.sim.q[1] - 0.02) < 1e-4


def test_watchdog_trips_when_set_points_stop(arm):
    timeout = ModuleTiming().watchdog_timeout
    enable(arm, 0.0)
    arm.advance(0.002 + timeout - 0.01)
    assert [m.flags for m in arm.modules] == [0] * 6       # not yet
    arm.advance(0.002 + timeout + 0.01)
    assert [m.flags for m in arm.modules] == [WATCHDOG | NOT_ENABLED] * 6
    flags = [r.error_flags for r in setpoints(arm, arm.positions(), 0.4)]
    assert flags == [0x0C] * 6                              # set-points again: stays tripped
    command_all(arm, protocol.RESET_ERRORS, 0.41)
    command_all(arm, protocol.ENABLE, 0.42)
    assert [r.error_flags for r in setpoints(arm, arm.positions(), 0.43)] == [0] * 6


def test_a_late_simulator_does_not_trip_the_watchdog(arm):
    """Set-points read late (the simulator held up 0.4 s) count as arriving when read."""
    enable(arm, 0.0)
    replies = setpoints(arm, arm.positions(), 0.4)        # first frame taken after the stall
    assert [r.error_flags for r in replies] == [0] * 6
    arm.advance(0.4)
    assert [m.flags for m in arm.modules] == [0] * 6


def test_a_disabled_module_has_no_watchdog(arm):
    setpoints(arm, arm.positions(), 0.0)
    command_all(arm, protocol.RESET_ERRORS, 0.0)
    arm.advance(2.0)
    assert [m.flags for m in arm.modules] == [NOT_ENABLED] * 6


def keep_alive(arm, t0, t1):
    """Stream set-points at the present position from ``t0`` to ``t1``; return the last replies."""
    t = t0
    while True:
        replies = setpoints(arm, arm.positions(), t)
        if t >= t1:
            return replies
        t = min(t + CYCLE, t1)
        arm.advance(t)


def test_referencing_needs_the_command_twice(arm):
    timing = ModuleTiming()
    enable(arm, 0.0)
    send(arm, 2, protocol.START_REFERENCING, 0.01)
    replies = keep_alive(arm, 0.02, 0.02 + timing.reference_time + 0.2)
    assert not replies[1].referenced
    t = 0.02 + timing.reference_time + 0.2 + timing.reference_window + 0.1
    keep_alive(arm, 0.8, t)
    send(arm, 2, protocol.START_REFERENCING, t)
    send(arm, 2, protocol.START_REFERENCING, t + 0.02)       # 20 ms apart, as the vendor
    assert not keep_alive(arm, t + 0.03, t + 0.03 + timing.reference_time - 0.1)[1].referenced
    replies = keep_alive(arm, t + 0.03 + timing.reference_time - 0.05,
                         t + 0.03 + timing.reference_time + 0.1)
    assert replies[1].referenced and replies[1].inputs & 0x80
    assert [r.referenced for r in replies] == [False, True, False, False, False, False]
    assert replies[1].error_flags == 0


def test_referencing_needs_the_motor_enabled(arm):
    setpoints(arm, arm.positions(), 0.0)
    command_all(arm, protocol.RESET_ERRORS, 0.0)
    send(arm, 4, protocol.START_REFERENCING, 0.01)
    send(arm, 4, protocol.START_REFERENCING, 0.03)
    arm.advance(2.0)
    assert not setpoints(arm, arm.positions(), 2.0)[3].referenced


@pytest.mark.parametrize('gap,zeroed', [(0.02, True), (0.45, True), (0.6, False)])
def test_set_zero_needs_the_command_twice_within_half_a_second(arm, gap, zeroed):
    setpoints(arm, arm.positions(), 0.0)
    before = setpoints(arm, arm.positions(), 0.0)[4].position
    assert before == 500
    send(arm, 5, protocol.SET_ZERO, 0.01)
    assert setpoints(arm, arm.positions(), 0.011)[4].position == before     # once: nothing
    send(arm, 5, protocol.SET_ZERO, 0.01 + gap)
    after = setpoints(arm, arm.positions(), 0.02 + gap)
    assert after[4].position == (0 if zeroed else before)
    assert [r.position for r in after[:4]] == [0, 0, 0, 0]


def test_injected_flags_stop_the_motor_and_reset_clears_them(arm):
    enable(arm, 0.0)
    arm.inject_flags(3, 0x20, 0.01)
    replies = setpoints(arm, arm.positions(), 0.02)
    assert replies[2].error_flags == 0x20 | NOT_ENABLED
    assert not arm.modules[2].enabled and arm.modules[1].enabled
    command_all(arm, protocol.ENABLE, 0.03)                 # enable alone does not clear it
    assert setpoints(arm, arm.positions(), 0.04)[2].error_flags == 0x24
    send(arm, 3, protocol.RESET_ERRORS, 0.05)
    send(arm, 3, protocol.ENABLE, 0.06)
    assert setpoints(arm, arm.positions(), 0.07)[2].error_flags == 0


def test_a_sticky_flag_survives_a_reset(arm):
    enable(arm, 0.0)
    arm.inject_flags(6, 0x40, 0.01, sticky=True)
    send(arm, 6, protocol.RESET_ERRORS, 0.02)
    send(arm, 6, protocol.ENABLE, 0.03)
    assert setpoints(arm, arm.positions(), 0.04)[5].error_flags == 0x44


def test_a_silent_module_acts_but_does_not_answer(arm):
    setpoints(arm, arm.positions(), 0.0)
    arm.set_silent(2, True)
    assert send(arm, 2, protocol.encode_setpoint(0, 1), 0.01) == []
    send(arm, 2, protocol.RESET_ERRORS, 0.02)
    arm.set_silent(2, False)
    assert send(arm, 2, protocol.encode_setpoint(0, 2), 0.03)[0].error_flags == NOT_ENABLED


@pytest.mark.parametrize('bad', [0, 256, -1, True, 1.5])
def test_bad_injections_are_refused(arm, bad):
    with pytest.raises(ValueError):
        arm.inject_flags(1, bad, 0.0)
    with pytest.raises(ValueError):
        arm.inject_flags(bad if bad not in (1, True) else 7, 0x10, 0.0)
    assert [m.flags for m in arm.modules] == [POWER_UP_FLAGS] * 6


def test_home_position_reads_in_ticks():
    q = np.array([0.5, -0.3, 0.2, 1.0, -0.5, 0.7])
    arm = build_arm(home_q=q)
    replies = setpoints(arm, arm.positions(), 0.0)
    for reply, scale, qi in zip(replies, arm.scales, q):
        assert reply.position == round(qi * scale.ticks_per_rad) + scale.offset
    assert math.copysign(1, arm.scales[2].ticks_per_rad) == 1       # J3's gear is positive


def test_each_module_keeps_the_frames_it_took_until_asked(arm):
    """``take_frames``: every frame in order (set-points with their ticks), then forgotten."""
    send(arm, 2, protocol.RESET_ERRORS, 0.0)
    send(arm, 2, protocol.encode_setpoint(123, 1), 0.05)
    send(arm, 2, b'\x01', 0.06)                      # a wrong length: ignored, not taken
    send(arm, 2, protocol.DISABLE, 0.1)
    taken = arm.take_frames()
    assert taken[1] == {'frames': [[0.0, 'reset', None], [0.05, 'setpoint', 123],
                                   [0.1, 'disable', None]], 'lost': 0}
    assert all(m == {'frames': [], 'lost': 0} for i, m in enumerate(taken) if i != 1)
    assert arm.take_frames()[1] == {'frames': [], 'lost': 0}


def test_the_frames_kept_are_bounded_and_the_lost_ones_counted(arm):
    from sim_bridge.can_arm import FRAMES_KEPT
    for k in range(FRAMES_KEPT + 5):
        send(arm, 1, protocol.DISABLE, k * 1e-4)
    taken = arm.take_frames()[0]
    assert len(taken['frames']) == FRAMES_KEPT and taken['lost'] == 5
    assert taken['frames'][0][0] == pytest.approx(5e-4)
