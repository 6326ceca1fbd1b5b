"""Jogging core (control/servo.py): lines held, every stop with its reason, limits respected."""

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st
from mover6_control.control.servo import (arm_reach, command_age, condition, damped_rates,
                                          FUTURE_STAMP_TOLERANCE, initial_state,
                                          joint_jog_command, JointJogCommand,
                                          normalised_jacobian, pose_and_jacobian, servo_step,
                                          ServoConfig, TwistCommand)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, jacobian, joint_rates
from mover6_control.kinematics.rotations import rotation_angle_between
import numpy as np
import pytest

ARM = mover6()
DT = 0.01
Q_AWAY = np.array([0.0, 0.3, 0.6, 0.0, 0.8, 0.0])     # away from home (q5 = 0: singular)
CONFIG = ServoConfig()


def run(q, command_at, seconds, config=CONFIG, extra=0.0):
    """Jog with perfect tracking for ``seconds`` (+ ``extra`` without new commands)."""
    state, outs = initial_state(ARM), []
    for k in range(int(round((seconds + extra) / DT))):
        now = k * DT
        command = command_at(min(now, seconds))
        out = servo_step(ARM, config, state, command, q, now, DT, ARM.velocity_limits)
        state = out.state
        q = q + out.qd * DT
        outs.append(out)
    return q, outs


def line_errors(T0, T1, direction):
    """Return (travel along the unit ``direction``, distance off its line, rotation) [m, rad]."""
    d = T1[:3, 3] - T0[:3, 3]
    along = float(d @ direction)
    return along, float(np.linalg.norm(d - along * direction)), rotation_angle_between(
        T0[:3, :3], T1[:3, :3])


@pytest.mark.parametrize('frame', ['base_link', 'link6'])
def test_a_twist_moves_the_flange_along_its_line(frame):
    """+0.02 m/s along x for 2 s: 40 mm along x of the frame, on the line, orientation kept."""
    T0 = fk(ARM, Q_AWAY)
    q, outs = run(Q_AWAY, lambda t: TwistCommand(t, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], frame),
                  2.0)
    x = np.array([1.0, 0.0, 0.0]) if frame == 'base_link' else T0[:3, 0]
    along, off, rot = line_errors(T0, fk(ARM, q), x)
    assert 0.038 < along < 0.0405
    assert off < 1e-4 and rot < 1e-3
    assert all(not out.halted for out in outs)


def test_the_reference_term_pulls_the_flange_back_onto_the_line():
    """A flange 5 mm off its reference line is brought back while it moves on."""
    state = initial_state(ARM)
    command = TwistCommand(0.0, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0])
    out = servo_step(ARM, CONFIG, state, command, Q_AWAY, 0.0, DT, ARM.velocity_limits)
    reference = out.state.reference
    q = Q_AWAY + np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])      # pushed off the line
    off0 = np.linalg.norm(fk(ARM, q)[:3, 3] - reference[:3, 3])
    state = out.state
    for k in range(1, 200):
        out = servo_step(ARM, CONFIG, state, TwistCommand(k * DT, [0.02, 0, 0], [0, 0, 0]), q,
                         k * DT, DT, ARM.velocity_limits)
        state, q = out.state, q + out.qd * DT
    T = fk(ARM, q)
    p0 = fk(ARM, Q_AWAY)[:3, 3]
    d = T[:3, 3] - p0
    assert off0 > 0.004
    assert np.linalg.norm(d - d[0] * np.array([1.0, 0.0, 0.0])) < 0.1 * off0


def test_stale_commands_decelerate_to_rest_within_the_acceleration_limit():
    """After the timeout (by stamp) the command falls to zero, within a_max, and says so."""
    q, outs = run(Q_AWAY, lambda t: JointJogCommand(t, [0.3, 0, 0, 0, 0, 0]), 1.0, extra=0.6)
    last = int(round(1.0 / DT))
    assert not outs[last + 9].stale and outs[last + 11].stale
    assert 'stale' in outs[last + 11].reason and outs[-1].at_rest
    speeds = np.array([out.qd[0] for out in outs])
    assert np.all(np.abs(np.diff(speeds)) <= CONFIG.a_max * DT + 1e-12)
    assert speeds[last + 9] == pytest.approx(0.3)


def test_no_command_is_a_reasoned_rest():
    """Before any command: zero, halted, with the reason."""
    out = servo_step(ARM, CONFIG, initial_state(ARM), None, Q_AWAY, 0.0, DT, ARM.velocity_limits)
    assert out.at_rest and out.halted and out.reason == 'no command yet'


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-5.0, 5.0), min_size=6, max_size=6))
def test_speed_limit_is_one_common_factor(velocities):
    """Any joint jog comes out within the limits and parallel to what was asked."""
    big = np.array(velocities)
    config = ServoConfig(a_max=1e6, joint_limit_margin=0.0)
    out = servo_step(ARM, config, initial_state(ARM), JointJogCommand(0.0, big), Q_AWAY, 0.0, DT,
                     ARM.velocity_limits)
    assert np.all(np.abs(out.qd) <= ARM.velocity_limits + 1e-12)
    if np.linalg.norm(big) > 1e-6:
        cos = out.qd @ big / (np.linalg.norm(out.qd) * np.linalg.norm(big))
        assert cos == pytest.approx(1.0)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.3, 0.3)),
                min_size=5, max_size=30))
def test_acceleration_and_speed_limits_hold_for_any_command_sequence(commands):
    """Whatever twists come, every tick stays within the speed limits and a_max per joint."""
    state, q = initial_state(ARM), Q_AWAY.copy()
    for k, (vx, vz, wz) in enumerate(commands):
        out = servo_step(ARM, CONFIG, state, TwistCommand(k * DT, [vx, 0, vz], [0, 0, wz]), q,
                         k * DT, DT, ARM.velocity_limits)
        assert np.all(np.abs(out.qd - state.qd) <= CONFIG.a_max * DT + 1e-12)
        assert np.all(np.abs(out.qd) <= ARM.velocity_limits + 1e-12)
        state, q = out.state, q + out.qd * DT


def wrist_twist(q, sign):
    """Return the twist that turns joint 5 alone at 0.2 rad/s (sign -1: towards q5 = 0)."""
    column = jacobian(ARM, q)[:, 4] * 0.2 * sign
    return lambda t: TwistCommand(t, column[:3], column[3:])


def test_towards_the_wrist_singularity_slows_then_halts_before_it():
    """Slowed past the lower threshold, halted before the hard one, with the reason."""
    q, outs = run(Q_AWAY, wrist_twist(Q_AWAY, -1.0), 6.0)
    reasons = [out.reason for out in outs]
    assert any(r.startswith('slowed') for r in reasons)
    assert 'halted before a singularity' in reasons[-1] and outs[-1].at_rest
    assert condition(normalised_jacobian(ARM, q)) < CONFIG.hard_stop_singularity_threshold
    assert q[4] > 0.1
    speeds = [abs(out.qd[4]) for out in outs]
    slowed = next(k for k, r in enumerate(reasons) if r.startswith('slowed'))
    assert max(speeds[slowed + 5:]) < max(speeds[:slowed])
    # Away from it: free again, not slowed.
    q2, outs2 = run(q, wrist_twist(q, 1.0), 0.5)
    assert q2[4] > q[4] + 0.05
    assert all(not out.halted and out.scale == 1.0 for out in outs2)


def test_measure_is_scale_free():
    """The same arm twice as big has the same normalised Jacobian, hence the same measure."""
    origins = ARM.origins.copy()
    origins[:, :3, 3] *= 2.0
    tool = ARM.tool.copy()
    tool[:3, 3] *= 2.0
    big = replace(ARM, origins=origins, tool=tool)
    assert arm_reach(big) == pytest.approx(2.0 * arm_reach(ARM))
    assert np.allclose(normalised_jacobian(big, Q_AWAY), normalised_jacobian(ARM, Q_AWAY))
    assert condition(jacobian(big, Q_AWAY)) != pytest.approx(condition(jacobian(ARM, Q_AWAY)))


def test_damped_rates_are_the_kinematics_joint_rates():
    """Without normalisation the jogging solve is kinematics.forward.joint_rates."""
    twist = np.array([0.01, -0.02, 0.03, 0.1, 0.0, -0.1])
    assert np.allclose(damped_rates(jacobian(ARM, Q_AWAY), twist, 1e-3),
                       joint_rates(ARM, Q_AWAY, twist, 1e-3))
    T, J = pose_and_jacobian(ARM, Q_AWAY, 1.0)
    assert np.allclose(T, fk(ARM, Q_AWAY)) and np.allclose(J, jacobian(ARM, Q_AWAY))


def test_a_joint_near_its_limit_halts_towards_it_and_moves_away():
    """Towards the limit: halted with the joint named; away: moves."""
    q = Q_AWAY.copy()
    q[0] = ARM.upper[0] - 0.05
    toward = servo_step(ARM, CONFIG, initial_state(ARM),
                        JointJogCommand(0.0, [0.2, 0, 0, 0, 0, 0]), q, 0.0, DT,
                        ARM.velocity_limits)
    assert toward.halted and 'joint1' in toward.reason and 'upper limit' in toward.reason
    assert toward.at_rest
    away = servo_step(ARM, CONFIG, initial_state(ARM),
                      JointJogCommand(0.0, [-0.2, 0, 0, 0, 0, 0]), q, 0.0, DT,
                      ARM.velocity_limits)
    assert not away.halted and away.qd[0] < 0.0


def test_the_veto_hook_halts_with_its_reason():
    """A veto (the collision check) sees the poses up to where it could stop; halts with why."""
    seen = []

    def veto(q, q_next):
        seen.append((q.copy(), q_next.copy()))
        return 'link4 would hit the table' if q_next[1] > q[1] else None

    config = ServoConfig(veto=veto)
    out = servo_step(ARM, config, initial_state(ARM), JointJogCommand(0.0, [0, 0.2, 0, 0, 0, 0]),
                     Q_AWAY, 0.0, DT, ARM.velocity_limits)
    assert out.halted and out.reason == 'halted: vetoed: link4 would hit the table'
    # It sees the pose one tick ahead plus the distance to stop from 0.2 rad/s at a_max.
    ahead = 0.2 * DT + 0.2 ** 2 / (2.0 * config.a_max)
    assert seen and np.allclose(seen[0][1] - seen[0][0], [0, ahead, 0, 0, 0, 0])
    out = servo_step(ARM, config, initial_state(ARM), JointJogCommand(0.0, [0, -0.2, 0, 0, 0, 0]),
                     Q_AWAY, 0.0, DT, ARM.velocity_limits)
    assert not out.halted and out.qd[1] < 0.0


def test_joint_jog_by_name():
    """Names map to the arm's joints; unnamed joints stay; bad names are refused."""
    command = joint_jog_command(ARM, 1.0, ['joint3', 'joint1'], [0.1, -0.2])
    assert np.allclose(command.velocities, [-0.2, 0, 0.1, 0, 0, 0])
    for names, values in ((['joint9'], [0.1]), (['joint1', 'joint1'], [0.1, 0.1]),
                          (['joint1'], [0.1, 0.2]), ([], [])):
        with pytest.raises(InvalidInputError):
            joint_jog_command(ARM, 1.0, names, values)


def test_bad_commands_and_settings_are_refused():
    """Non-finite twists, unknown frames and inverted thresholds raise with a reason."""
    with pytest.raises(InvalidInputError, match='frame'):
        TwistCommand(0.0, [0, 0, 0], [0, 0, 0], 'world')
    with pytest.raises(InvalidInputError, match='finite'):
        TwistCommand(0.0, [np.nan, 0, 0], [0, 0, 0])
    with pytest.raises(InvalidInputError, match='hard_stop'):
        ServoConfig(lower_singularity_threshold=30.0, hard_stop_singularity_threshold=17.0)
    with pytest.raises(InvalidInputError, match='command_timeout'):
        ServoConfig(command_timeout=0.0)


def test_a_vanishing_twist_keeps_everything_finite():
    """A twist of denormal values (found by the property test) leaves no NaN behind."""
    state, q = initial_state(ARM), Q_AWAY.copy()
    for k, vx in enumerate([0.02, 5e-324, 5e-324, 0.02]):
        out = servo_step(ARM, CONFIG, state, TwistCommand(k * DT, [vx, 0, 0], [0, 0, 0]), q,
                         k * DT, DT, ARM.velocity_limits)
        assert np.all(np.isfinite(out.qd)) and np.all(np.isfinite(out.state.reference))
        state, q = out.state, q + out.qd * DT


def test_late_and_skipped_ticks_do_not_leave_the_reference_behind():
    """Ticks 5 to 30 ms apart (the arm moving on meanwhile): still ~40 mm in 2 s, on the line."""
    rng = np.random.default_rng(3)
    q, state, now = Q_AWAY.copy(), initial_state(ARM), 0.0
    T0 = fk(ARM, q)
    while now < 2.0:
        out = servo_step(ARM, CONFIG, state, TwistCommand(now, [0.02, 0, 0], [0, 0, 0]), q, now,
                         DT, ARM.velocity_limits)
        step = float(rng.uniform(0.005, 0.03))
        state, q, now = out.state, q + out.qd * step, now + step
    along, off, rot = line_errors(T0, fk(ARM, q), np.array([1.0, 0.0, 0.0]))
    assert 0.038 < along < 0.041 and off < 2e-4 and rot < 1e-3     # was 35.5 mm


HUGE_TWISTS = [([1e308, 0.0, 0.0], [0.0, 0.0, 0.0]),
               ([1e300, 1e308, -1e300], [1e300, 1e307, 1e300]),
               ([-1.7e308, 1.7e308, 1.7e308], [1.7e308, -1.7e308, 1.7e308])]


@pytest.mark.parametrize('frame', ['base_link', 'link6'])
@pytest.mark.parametrize('q0', [Q_AWAY, np.zeros(6)], ids=['away', 'home'])
@pytest.mark.parametrize('linear, angular', HUGE_TWISTS)
def test_a_huge_twist_gives_the_command_of_the_largest_twist_the_joints_can_follow(
        linear, angular, q0, frame):
    """1e308 m/s (NaN rates and a raise at home before): finite, in the limits, as 1e3 would."""
    config = ServoConfig(a_max=100.0)         # at full speed in a tick or two

    def jog(size):
        return run(q0, lambda t: TwistCommand(t, np.array(linear) * size,
                                              np.array(angular) * size, frame), 0.3, config)

    q, outs = jog(1.0)
    assert np.all(np.isfinite(q))
    for out in outs:
        assert np.all(np.isfinite(out.qd)) and np.all(np.isfinite(out.state.reference))
        assert np.all(np.abs(out.qd) <= ARM.velocity_limits * (1.0 + 1e-12))
    if not outs[-1].halted and outs[-1].scale == 1.0:     # not held at a singularity: flat out
        assert np.max(np.abs(outs[-1].qd) / ARM.velocity_limits) == pytest.approx(1.0)
    # The same direction as a twist merely far too fast (the speed limit takes both down).
    q_fast, outs_fast = jog(1e3 / max(np.max(np.abs(linear)), np.max(np.abs(angular))))
    np.testing.assert_allclose(outs[0].qd, outs_fast[0].qd, rtol=1e-6, atol=1e-12)


def test_a_huge_joint_jog_moves_at_the_speed_limit():
    """1e308 rad/s on joint 2 (a zero command before: inf in the speed factor) is its limit."""
    config = ServoConfig(a_max=1e6)
    out = servo_step(ARM, config, initial_state(ARM), JointJogCommand(0.0, [0, 1e308, 0, 0, 0, 0]),
                     Q_AWAY, 0.0, DT, ARM.velocity_limits)
    np.testing.assert_allclose(out.qd, [0, ARM.velocity_limits[1], 0, 0, 0, 0])


def test_a_future_stamp_is_refused_and_age_counts_from_arrival():
    """A stamp 1 s after its arrival is refused; one within the tolerance ages from arrival."""
    with pytest.raises(InvalidInputError, match='in the future'):
        TwistCommand(11.0, [0.02, 0, 0], [0, 0, 0], received=10.0)
    with pytest.raises(InvalidInputError, match='in the future'):
        joint_jog_command(ARM, 3610.0, ['joint1'], [0.1], received=10.0)
    early = 0.9 * FUTURE_STAMP_TOLERANCE
    command = JointJogCommand(10.0 + early, [0.3, 0, 0, 0, 0, 0], received=10.0)
    assert command_age(command, 10.0 + early) == pytest.approx(early)
    old = TwistCommand(9.5, [0.02, 0, 0], [0, 0, 0], received=10.0)      # late: by its stamp
    assert command_age(old, 10.0) == pytest.approx(0.5)
    state = initial_state(ARM, [0.3, 0, 0, 0, 0, 0])
    for now, stale in ((10.09, False), (10.0 + CONFIG.command_timeout + 0.005, True)):
        out = servo_step(ARM, CONFIG, state, command, Q_AWAY, now, DT, ARM.velocity_limits)
        assert out.stale == stale, now


FINITE = st.floats(allow_nan=False, allow_infinity=False)
SPECIAL = st.sampled_from([0.0, 5e-324, -5e-324, 2.2e-308, 1e-300, 1e308, -1e308, 1.7976e308,
                           -1.7976e308, 1e-3, -0.02])
COMPONENT = st.one_of(FINITE, SPECIAL)
CONFIGURATION = st.tuples(*[st.floats(float(lo), float(hi))
                            for lo, hi in zip(ARM.lower, ARM.upper)])


@settings(max_examples=60, deadline=None)
@given(st.lists(COMPONENT, min_size=6, max_size=6), CONFIGURATION,
       st.sampled_from(['base_link', 'link6', 'joints']),
       st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_any_finite_command_gives_a_finite_command_within_the_limits(values, q, frame, qd0):
    """Any finite twist or joint jog (1e308, denormals), any q in the limits, any speed before."""
    q = np.array(q)
    vlim = ARM.velocity_limits
    state = initial_state(ARM, np.array(qd0) * vlim)
    for k in range(3):
        now = k * DT
        command = (JointJogCommand(now, values) if frame == 'joints'
                   else TwistCommand(now, values[:3], values[3:], frame))
        out = servo_step(ARM, CONFIG, state, command, q, now, DT, vlim)
        assert np.all(np.isfinite(out.qd)), out.qd
        assert np.all(np.abs(out.qd) <= vlim * (1.0 + 1e-12)), out.qd
        assert np.all(np.abs(out.qd - state.qd) <= CONFIG.a_max * DT * (1.0 + 1e-9)), out.qd
        assert out.state.reference is None or np.all(np.isfinite(out.state.reference))
        state, q = out.state, np.clip(q + out.qd * DT, ARM.lower, ARM.upper)
