"""The ROS-free simulator: commands, timeout, limits, reset, vendor-driver mode and pacing."""

import math

from core_testing import send_demand, send_states
from hypothesis import given, settings, strategies as st
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.profiles import LawConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6, MOVER6_TICK_SIZE
import mujoco
import numpy as np
import pytest
from sim_bridge.model import ModelOptions
from sim_bridge.pacing import steps_due
from sim_bridge.simulator import SimConfig, Simulator

ARM = mover6('hardware')
NAMES = ARM.joint_names
VMAX = ARM.velocity_limits
TICK = np.array(MOVER6_TICK_SIZE)
VENDOR = SimConfig(mode='vendor_driver')


def _servo_lag(sim):
    """Return the servo's time constant bound [s]: largest joint inertia / kv at the pose."""
    M = np.zeros((sim.model.nv, sim.model.nv))
    mujoco.mj_fullM(sim.model, sim.data, M)
    return float(np.max(np.diag(M))) / sim.config.model.kv


# --- rad_per_s: integration, clamping, timeout ---------------------------------------------

@settings(max_examples=15, deadline=None)
@given(frac=st.tuples(*[st.floats(-0.95, 0.95) for _ in range(6)]).map(np.array))
def test_constant_velocity_integrates_to_the_expected_position(frac):
    """A constant JointJog velocity, renewed at 100 Hz, moves each joint by v * T."""
    sim = Simulator(ARM)
    v = frac * VMAX
    duration = 0.5
    t0, q0 = sim.time, sim.q
    lag = _servo_lag(sim)
    while sim.time < t0 + duration - 1e-9:
        sim.set_command(NAMES, v, sim.time)
        sim.step(5)
    # The servo starts from rest, so a joint lags by about |v| M / kv, and the coupled inertia
    # passes a transient of the same order to the other joints; then it tracks exactly.
    err = np.abs(sim.q - q0 - v * (sim.time - t0))
    assert np.all(err <= np.max(np.abs(v)) * 2.0 * lag + 1e-6), (err, lag)
    np.testing.assert_allclose(sim.qd, v, atol=1e-4)


def test_speed_above_the_limit_is_clamped_with_a_warning():
    """A joint asked to go faster than its limit goes at its limit; the command says so."""
    sim = Simulator(ARM)
    v = np.array([2.0, 0.1, 0.0, 0.0, -5.0, 0.0])
    warnings = sim.set_command(NAMES, v, sim.time)
    assert len(warnings) == 2 and 'joint1' in warnings[0] and 'joint5' in warnings[1]
    sim.run_for(0.1)
    np.testing.assert_allclose(sim.qd, [VMAX[0], 0.1, 0, 0, -VMAX[4], 0], atol=1e-4)


def test_stale_command_halts_within_timeout_plus_one_step():
    """The last step using a command starts at most command_timeout after its receipt."""
    cfg = SimConfig(command_timeout=0.2)
    sim = Simulator(ARM, cfg)
    dt = cfg.physics_dt
    v = 0.8 * VMAX * np.array([1, -1, 1, -1, 1, -1])
    sim.run_for(0.01)
    t_rx = sim.time
    sim.set_command(NAMES, v, t_rx)
    while sim.time < t_rx + cfg.command_timeout - 1e-9:
        sim.step()
        np.testing.assert_array_equal(sim.ctrl, v)
    sim.step()                        # the one step allowed after the timeout
    assert sim.time <= t_rx + cfg.command_timeout + dt + 1e-9
    assert sim.is_stale()
    sim.step()
    np.testing.assert_array_equal(sim.ctrl, np.zeros(6))
    assert np.all(np.abs(sim.qd) <= 0.1 * np.abs(v))       # the stiff servo brakes at once
    sim.run_for(0.02)
    assert np.all(np.abs(sim.qd) <= 1e-4)
    q_halt = sim.q
    sim.run_for(0.5)
    np.testing.assert_allclose(sim.q, q_halt, atol=1e-6)


def test_fresh_commands_keep_the_arm_moving():
    """Commands renewed faster than the timeout never let the arm halt."""
    sim = Simulator(ARM, SimConfig(command_timeout=0.05))
    v = 0.3 * VMAX
    for _ in range(40):
        sim.set_command(NAMES, v, sim.time)
        sim.run_for(0.04)
        assert not sim.is_stale()
    np.testing.assert_allclose(sim.qd, v, atol=1e-4)


def test_at_rest_while_nothing_moves_the_arm():
    """At rest: no command, a zero one or a stale one, and every joint still; else not."""
    sim = Simulator(ARM)
    assert sim.at_rest()                          # no command yet, still
    sim.set_command(NAMES, np.zeros(6), sim.time)
    sim.step(5)
    assert sim.at_rest()                          # a zero command moves nothing
    v = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.2])
    sim.set_command(NAMES, v, sim.time)
    assert not sim.at_rest()                      # commanded to move, before its first step
    sim.step(50)
    assert not sim.at_rest()
    sim.run_for(sim.config.command_timeout + 0.01)    # stale: halted, braking
    assert sim.is_stale()
    while abs(sim.qd[5]) >= 1e-4:
        sim.step()
        assert not sim.at_rest()                  # still moving faster than STILL_SPEED
    assert sim.at_rest()
    assert not Simulator(ARM, VENDOR).at_rest()   # vendor mode: the driver's cycle rules


def test_partial_command_zeroes_the_other_joints():
    """In rad_per_s mode a command naming some joints stops the others (MoveIt Servo)."""
    sim = Simulator(ARM)
    sim.set_command(NAMES, 0.2 * VMAX, sim.time)
    sim.set_command(['joint3'], [0.3], sim.time)
    sim.run_for(0.05)
    np.testing.assert_allclose(sim.qd, [0, 0, 0.3, 0, 0, 0], atol=1e-4)


BAD_COMMANDS = [
    (['joint7'], [0.1], 'unknown'),
    (['joint1', 'wrist'], [0.1, 0.1], 'unknown'),
    (['joint1', 'joint2'], [0.1], 'names but'),
    (['joint1'], [0.1, 0.2], 'names but'),
    ([], [], 'no joints'),
    (['joint1', 'joint1'], [0.1, 0.1], 'twice'),
    (['joint1'], [float('nan')], 'non-finite'),
    (['joint1'], [float('inf')], 'non-finite'),
    (['joint1'], ['fast'], 'not numbers'),
]


@pytest.mark.parametrize('mode', ['rad_per_s', 'vendor_driver'])
@pytest.mark.parametrize('names,values,reason', BAD_COMMANDS)
def test_bad_commands_are_rejected_and_change_nothing(mode, names, values, reason):
    """Every kind of bad command raises with a reason; the held command and motion go on."""
    sim = Simulator(ARM, SimConfig(mode=mode))
    good = np.full(6, 0.5) if mode == 'vendor_driver' else 0.2 * VMAX
    sim.set_command(NAMES, good, sim.time)
    sim.run_for(0.1)
    count = sim.command_count
    with pytest.raises(InvalidInputError, match=reason):
        sim.set_command(names, values, sim.time)
    assert sim.command_count == count
    np.testing.assert_array_equal(sim.held_command, good)
    q = sim.q
    sim.run_for(0.1)
    assert np.all(np.abs(sim.q - q)[:4] > 1e-3)     # still moving under the good command


def test_joints_stop_at_their_limits():
    """Driving into a limit stops the joint there, never beyond."""
    sim = Simulator(ARM, home_q=ARM.upper - 0.05)
    for _ in range(40):
        sim.set_command(NAMES, VMAX, sim.time)
        sim.run_for(0.05)
    assert np.all(sim.q <= ARM.upper + 1e-6)
    np.testing.assert_allclose(sim.q, ARM.upper, atol=1e-3)
    sim.set_command(NAMES, -0.5 * VMAX, sim.time)
    sim.run_for(0.1)
    assert np.all(sim.q < ARM.upper - 0.01)         # and it can come back


# --- reset ---------------------------------------------------------------------------------

def _drive(sim, v, duration):
    """Command ``v`` at 100 Hz for ``duration`` [s] and return the positions every 10 ms."""
    out = []
    for _ in range(int(round(duration / 0.01))):
        sim.set_command(NAMES, v, sim.time)
        sim.run_for(0.01)
        out.append(sim.q)
    return np.array(out)


@pytest.mark.parametrize('mode', ['rad_per_s', 'vendor_driver'])
def test_reset_restores_the_state(mode):
    """After a reset the arm is at rest at home, commands are gone, time has not gone back."""
    cfg = SimConfig(mode=mode)
    home = np.array([0.1, 0.2, -0.3, 0.0, 0.4, -0.5])
    scale = 1.0 if mode == 'vendor_driver' else 0.5 * VMAX
    v = np.array([0.9, -0.8, 0.7, 0.9, -0.9, 0.8]) * scale
    fresh = Simulator(ARM, cfg, home_q=home)
    expected = _drive(fresh, v, 0.5)
    sim = Simulator(ARM, cfg, home_q=home)
    _drive(sim, -v, 0.7)
    t_before = sim.time
    sim.reset()
    np.testing.assert_array_equal(sim.q, home)
    np.testing.assert_array_equal(sim.qd, np.zeros(6))
    np.testing.assert_array_equal(sim.held_command, np.zeros(6))
    assert sim.time == t_before
    np.testing.assert_allclose(sim.state().q, np.round(home / TICK) * TICK
                               if mode == 'vendor_driver' else home, atol=1e-12)
    # what follows a reset is what follows a new simulator
    np.testing.assert_allclose(_drive(sim, v, 0.5), expected, atol=1e-9)


def test_reset_to_a_given_configuration_and_refusals():
    """A reset goes to a given q; a q outside the limits or of the wrong size is refused."""
    sim = Simulator(ARM)
    q = np.array([0.5, 0.3, -0.2, 1.0, -0.5, 1.5])
    sim.reset(q)
    np.testing.assert_array_equal(sim.q, q)
    sim.run_for(0.2)
    np.testing.assert_allclose(sim.q, q, atol=1e-9)
    for bad in ([0.0] * 5, [9.0, 0, 0, 0, 0, 0], [float('nan')] * 6):
        with pytest.raises(InvalidInputError):
            sim.reset(bad)
    np.testing.assert_allclose(sim.q, q, atol=1e-9)
    with pytest.raises(InvalidInputError):
        Simulator(ARM, home_q=[0, 0, 0, 0, 3.0, 0])


def test_any_arm_from_urdf_in_rad_per_s_mode(tmp_path):
    """A two-joint arm runs in rad_per_s mode; vendor mode asks for its tick sizes."""
    from mover6_control.kinematics.arm import load_urdf
    urdf = tmp_path / 'two.urdf'
    urdf.write_text("""<?xml version="1.0"?>
<robot name="two">
  <link name="base_link"/><link name="a"/><link name="b"/>
  <joint name="ja" type="revolute"><parent link="base_link"/><child link="a"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="jb" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>
""")
    arm = load_urdf(str(urdf))
    sim = Simulator(arm)
    sim.set_command(['jb'], [0.5], sim.time)
    sim.run_for(0.2)
    assert abs(sim.q[1] - 0.1) < 1e-3 and abs(sim.q[0]) < 1e-6
    with pytest.raises(InvalidInputError, match='tick_size'):
        Simulator(arm, VENDOR)
    Simulator(arm, SimConfig(mode='vendor_driver', tick_size=(1e-4, 1e-4)))


# --- vendor_driver -------------------------------------------------------------------------

def test_vendor_moves_whole_ticks_per_cycle():
    """Each 50 ms cycle moves trunc(f * vmax * override * cycle / tick) whole ticks."""
    sim = Simulator(ARM, VENDOR)
    f = np.array([0.5, -0.3, 0.9, 0.2, 0.8, -0.6])
    sim.set_command(NAMES, f, sim.time)
    cycles = 20
    sim.run_for(cycles * VENDOR.vendor_cycle)
    ticks = np.trunc(f * VMAX * VENDOR.speed_override * VENDOR.vendor_cycle / TICK)
    np.testing.assert_allclose(sim.q, cycles * ticks * TICK, atol=2e-5)
    reading = sim.state()
    np.testing.assert_allclose(reading.q / TICK, np.round(reading.q / TICK), atol=1e-9)
    np.testing.assert_array_equal(reading.effort, np.zeros(6))
    assert math.isclose(reading.time / VENDOR.vendor_cycle,
                        round(reading.time / VENDOR.vendor_cycle), abs_tol=1e-6)


def test_vendor_small_commands_do_not_move_the_wrist():
    """Under one tick per cycle (about 7 deg/s) J5 and J6 do not move at all."""
    threshold = TICK * (1.0 / VENDOR.vendor_cycle)            # [rad/s]
    np.testing.assert_allclose(np.degrees(threshold[4:]), 7.03, atol=0.01)
    sim = Simulator(ARM, VENDOR)
    speed = np.full(6, 0.95 * threshold[4])                    # just under one wrist tick
    f = speed / (VMAX * VENDOR.speed_override)
    sim.set_command(NAMES, f, sim.time)
    sim.run_for(2.0)
    np.testing.assert_array_equal(sim.state().q[4:], 0.0)     # the encoders never tick
    np.testing.assert_allclose(sim.q[4:], 0.0, atol=1e-6)     # only the others' reaction
    assert np.all(sim.q[:4] > 0.01)                            # the big joints resolve it
    f_over = 1.05 * threshold[4:] / (VMAX[4:] * VENDOR.speed_override)   # just over
    sim.set_command(['joint5', 'joint6'], f_over, sim.time)
    sim.run_for(1.0)
    np.testing.assert_allclose(sim.q[4:], 20 * TICK[4:], atol=2e-5)


def test_vendor_holds_the_last_command_forever():
    """No timeout: the last command keeps the arm moving until zeros arrive."""
    sim = Simulator(ARM, VENDOR)
    sim.set_command(['joint1'], [0.5], sim.time)
    sim.run_for(2.0)
    assert not sim.is_stale()
    v = VMAX[0] * 0.5 * VENDOR.speed_override
    assert abs(sim.q[0] - 2.0 * v) < 0.01
    sim.set_command(['joint2'], [0.5], sim.time)             # joint1 keeps its fraction
    sim.run_for(1.0)
    assert abs(sim.q[0] - 3.0 * v) < 0.01 and sim.q[1] > 0.05
    sim.set_command(NAMES, np.zeros(6), sim.time)
    sim.run_for(0.5)
    q = sim.q
    np.testing.assert_allclose(q / TICK, np.round(q / TICK), atol=1e-6)   # on a whole tick
    sim.run_for(1.0)
    np.testing.assert_allclose(sim.q, q, atol=1e-9)


def test_vendor_fractions_are_clamped_and_override_scales():
    """A fraction above 1 is clamped with a warning; the override scales the speed."""
    slow = Simulator(ARM, SimConfig(mode='vendor_driver', speed_override=0.1))
    fast = Simulator(ARM, SimConfig(mode='vendor_driver', speed_override=0.5))
    for sim in (slow, fast):
        warnings = sim.set_command(['joint1'], [3.0], sim.time)
        assert warnings and 'clamped' in warnings[0]
        sim.run_for(1.0)
    assert abs(slow.q[0] - 0.1 * VMAX[0]) < 2e-3
    assert abs(fast.q[0] - 0.5 * VMAX[0]) < 2e-3


def test_controller_fraction_of_max_drives_vendor_mode_to_the_goal():
    """
    The controller core, in fraction_of_max units, brings the vendor-mode arm to its goal.

    Its loop runs at 100 Hz on the driver's 20 Hz tick-quantised readings. J5 and J6 resolve
    one tick (6.1 mrad), so their goal tolerance is one tick; the others keep 2 mrad. The gain
    of 10 1/s keeps the command of a one-tick error above the wrist's one-tick-per-cycle
    threshold (at the default 2 1/s the wrist stops about 0.05 rad short: the deadband).
    """
    sim = Simulator(ARM, VENDOR)
    tol = np.maximum(0.002, TICK)
    ctl = ControllerCore(ARM, ControllerConfig(law=LawConfig(profile='synchronised'),
                                               jog_units='fraction_of_max', position_gain=10.0,
                                               goal_tolerance=tol,
                                               speed_override=VENDOR.speed_override))
    goal = np.array([0.4, -0.3, 0.5, 0.6, -0.7, 0.9])
    last_reading, accepted = None, False
    for _ in range(3000):
        now = sim.time
        reading = sim.state()
        if reading.time != last_reading:
            send_states(ctl, now, reading.q, reading.qd)
            last_reading = reading.time
        if not accepted and ctl.state == 'idle':
            send_demand(ctl, now, goal[None])
            accepted = True
        out = ctl.tick(now)
        sim.set_command(NAMES, out.jog, now)
        sim.run_for(0.01)
        if accepted and out.state == 'idle':
            break
    assert ctl.status().values.get('result') == 'arrived', ctl.status().message
    assert np.all(np.abs(sim.q - goal) <= tol + 1e-9)


def test_a_physics_blow_up_is_reported():
    """A non-finite state makes MuJoCo reset; the simulator reports the warning."""
    sim = Simulator(ARM)
    assert sim.warnings() == {}
    sim.data.qvel[0] = float('nan')
    sim.step()
    assert sim.warnings().get('mjWARN_BADQVEL', 0) >= 1
    assert np.all(np.isfinite(sim.q))


# --- pacing --------------------------------------------------------------------------------

@settings(max_examples=50, deadline=None)
@given(sim_elapsed=st.floats(0.0, 100.0), lag=st.floats(-0.01, 0.05),
       rtf=st.floats(0.1, 10.0), dt=st.sampled_from([0.001, 0.0015, 0.002]))
def test_steps_due_keeps_sim_time_just_behind_paced_wall_time(sim_elapsed, lag, rtf, dt):
    """After the due steps sim time is within one step behind rtf * wall time, never ahead."""
    wall = (sim_elapsed + lag) / rtf
    n = steps_due(sim_elapsed, wall, rtf, dt, max_steps=10 ** 6)
    after = sim_elapsed + n * dt
    if lag > 0:
        assert wall * rtf - dt - 1e-6 < after <= wall * rtf + 1e-6
    else:
        assert n == 0


def test_steps_due_edges():
    """A factor of 0 runs flat out; a big lag is capped; bad factors are refused."""
    assert steps_due(0.0, 0.0, 0.0, 0.002, max_steps=50) == 50
    assert steps_due(0.0, 10.0, 1.0, 0.002, max_steps=50) == 50
    assert steps_due(0.0, 0.0101, 1.0, 0.002) == 5
    for bad in (-1.0, float('nan')):
        with pytest.raises(InvalidInputError):
            steps_due(0.0, 1.0, bad, 0.002)


@pytest.mark.parametrize('bad', [{'mode': 'turbo'}, {'command_timeout': 0.0},
                                 {'speed_override': 1.5}, {'speed_override': 0.0},
                                 {'vendor_cycle': 0.0005}, {'tick_size': (0.1, -1.0)},
                                 {'model': ModelOptions(physics_dt=0.002), 'vendor_cycle': 0.001}])
def test_config_is_checked(bad):
    """Nonsense settings are refused with a reason."""
    with pytest.raises(InvalidInputError):
        SimConfig(**bad)


def test_other_physics_steps_keep_the_behaviour():
    """At a 1 ms step the same command gives the same motion."""
    sim = Simulator(ARM, SimConfig(model=ModelOptions(physics_dt=0.001)))
    v = 0.4 * VMAX
    lag = _servo_lag(sim)
    q = _drive(sim, v, 0.3)[-1]
    assert np.all(np.abs(q - v * 0.3) <= np.max(np.abs(v)) * 2.0 * lag + 1e-6)


def test_refresh_is_the_same_command_again():
    """refresh_command(t) steps exactly as set_command(same command, t), timeout included."""
    cfg = SimConfig(command_timeout=0.05)
    a, b = Simulator(ARM, cfg), Simulator(ARM, cfg)
    v = 0.1 * VMAX
    for sim in (a, b):
        sim.set_command(NAMES, v, sim.time)
        sim.run_for(0.03)
    assert a.set_command(NAMES, v, a.time) == []
    assert b.refresh_command(b.time)
    for _ in range(60):                     # past the refreshed timeout: both halt alike
        a.step()
        b.step()
        np.testing.assert_array_equal(a.q, b.q)
        assert a.is_stale() == b.is_stale()
    assert a.is_stale() and a.command_count == b.command_count


def test_refresh_refuses_what_is_not_the_held_command():
    """No command, a stale one, an earlier or non-finite time, vendor mode: False, unchanged."""
    sim = Simulator(ARM, SimConfig(command_timeout=0.05))
    assert not sim.refresh_command(sim.time)             # no command yet
    sim.set_command(NAMES, np.zeros(6), sim.time)
    t = sim.time
    count = sim.command_count
    for bad in (t - 0.01, t + 0.06, math.nan, math.inf):
        assert not sim.refresh_command(bad)
    assert sim.command_count == count
    assert sim.refresh_command(t + 0.05)
    vendor = Simulator(ARM, SimConfig(mode='vendor_driver'))
    vendor.set_command(NAMES, np.zeros(6), vendor.time)
    assert not vendor.refresh_command(vendor.time)
