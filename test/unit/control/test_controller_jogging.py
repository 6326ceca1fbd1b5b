"""Jogging in the controller core: the state machine shared with motions, reasons on status."""

from dataclasses import replace

from core_testing import send_demand, send_states
from mover6_control.control import jogging
from mover6_control.control import state_machine as sm
from mover6_control.control.collision_guard import CollisionGuard
from mover6_control.control.controller_config import config_changes, ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.profiles import LawConfig
from mover6_control.control.servo import ServoConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, jacobian
import numpy as np
import pytest

DT = 0.01
Q_AWAY = np.array([0.0, 0.3, 0.6, 0.0, 0.8, 0.0])
GOAL = np.array([0.3, 0.2, 0.5, 0.1, 0.6, 0.2])


class Sim:
    """An arm that follows the command exactly and reports its state every tick."""

    def __init__(self, core, q0):
        self.core, self.q, self.t, self.log = core, np.array(q0, dtype=float), 0.0, []

    def tick(self, jog=None):
        """Report the states, send ``jog(core, t)`` if given, tick, integrate."""
        send_states(self.core, self.t, self.q)
        if jog is not None:
            jog(self.core, self.t)
        out = self.core.tick(self.t)
        self.log.append((self.t, out.state, out.qd.copy()))
        self.q = self.q + out.qd * DT
        self.t = round(self.t + DT, 9)
        return out


def make(**kw):
    core = ControllerCore(mover6(), ControllerConfig(law=LawConfig(profile='trapezoidal'), **kw))
    sim = Sim(core, Q_AWAY)
    sim.tick()
    assert core.state == sm.IDLE
    return core, sim


def twist_x(core, t):
    core.on_twist(t, t, [0.02, 0.0, 0.0], [0.0, 0.0, 0.0], 'base_link')


def test_a_twist_jogs_then_stale_commands_end_it_at_rest_with_the_reason():
    core, sim = make()
    p0 = fk(core.arm, sim.q)[:3, 3]
    for _ in range(200):
        out = sim.tick(twist_x)
        assert out.state == sm.JOGGING
    while sim.tick().state == sm.JOGGING:
        assert sim.t < 3.0
    d = fk(core.arm, sim.q)[:3, 3] - p0
    assert 0.038 < d[0] < 0.043 and np.hypot(d[1], d[2]) < 1e-4
    status = core.status()
    assert status.state == sm.IDLE and status.values['result'] == 'jog_stopped'
    assert 'stale' in status.values['reason']
    assert not np.any(sim.tick().qd)


def test_joint_jog_by_name():
    core, sim = make()
    for _ in range(50):
        sim.tick(lambda c, t: c.on_joint_jog(t, t, ['joint2'], [0.1]))
    assert sim.q[1] > Q_AWAY[1] + 0.03
    assert np.allclose(np.delete(sim.q, 1), np.delete(Q_AWAY, 1))
    with pytest.raises(InvalidInputError, match='unknown joint'):
        core.on_joint_jog(sim.t, sim.t, ['joint7'], [0.1])
    assert 'unknown joint' in core.status().values['jog_refused']


def test_jogging_is_refused_while_a_motion_executes():
    core, sim = make()
    send_demand(core, sim.t, [GOAL])
    sim.tick()
    with pytest.raises(InvalidInputError, match='jogging refused while executing'):
        twist_x(core, sim.t)
    assert 'stop the motion first' in core.status().values['jog_refused']
    assert core.state == sm.EXECUTING


def test_stale_command_does_not_start_a_jog():
    core, sim = make()
    with pytest.raises(InvalidInputError, match='older than the timeout'):
        core.on_twist(sim.t, sim.t - 0.5, [0.02, 0, 0], [0, 0, 0])
    assert core.state == sm.IDLE


def test_a_demand_while_jogging_takes_over_without_a_velocity_jump():
    core, sim = make()
    for _ in range(100):
        sim.tick(lambda c, t: c.on_joint_jog(t, t, ['joint1', 'joint3'], [0.3, -0.2]))
    before = sim.log[-1][2]
    assert np.max(np.abs(before)) > 0.15
    send_demand(core, sim.t, [GOAL])
    after = sim.tick().qd
    assert core.state == sm.EXECUTING
    assert np.max(np.abs(after - before)) <= 2 * core.config.law.a_max * DT
    while sim.tick().state != sm.IDLE:
        assert sim.t < 30.0
    np.testing.assert_allclose(sim.q, GOAL, atol=0.002)


def test_stop_while_jogging_decelerates():
    core, sim = make()
    for _ in range(50):
        sim.tick(twist_x)
    ok, _ = core.request_stop(sim.t)
    assert ok and core.state == sm.STOPPING
    while sim.tick().state != sm.IDLE:
        assert sim.t < 5.0
    assert core.status().values['result'] == 'stopped'


def test_singularity_halt_is_on_the_status():
    core, sim = make()
    column = -0.2 * jacobian(core.arm, sim.q)[:, 4]     # joint 5 alone, towards q5 = 0

    def towards(c, t):
        c.on_twist(t, t, column[:3], column[3:])

    for _ in range(600):
        sim.tick(towards)
    status = core.status()
    assert status.state == sm.JOGGING and status.level == 'WARN'
    assert 'halted before a singularity' in status.message
    assert 'halted before a singularity' in status.values['jog_reason']
    assert not np.any(sim.log[-1][2])


def test_servo_settings_changes_are_named_with_their_parameter():
    old = ControllerConfig()
    new = ControllerConfig(servo=ServoConfig(command_timeout=0.2))
    assert config_changes(old, new) == [('servo_command_timeout', 0.2)]


def test_a_jog_towards_the_table_halts_before_it_and_a_jog_away_moves():
    """With the collision check on, the jog's next poses are checked: it halts in time."""
    core, sim = make()
    guard = CollisionGuard(core.arm)
    core.collision_guard = guard
    sim.q = np.array([0.0, 0.3, 0.5, 0.0, 0.8, 0.0])        # flange down, 153 mm above z = 0
    sim.tick()
    assert guard.checker.check_configurations(sim.q[None]).free

    def down(core, t):
        core.on_twist(t, t, [0.0, 0.0, -0.03], [0.0, 0.0, 0.0], 'base_link')

    z0 = fk(core.arm, sim.q)[2, 3]
    reason = ''
    while not reason.startswith('halted: vetoed: collision ahead'):
        out = sim.tick(down)
        reason = core.status().values.get('jog_reason', '')
        assert out.state == sm.JOGGING and sim.t < 5.0, reason
        assert guard.checker.check_configurations(sim.q[None]).free
    assert 'table margin' in reason
    for _ in range(50):                                    # held there, still commanding down
        out = sim.tick(down)
        assert guard.checker.check_configurations(sim.q[None]).free
    assert np.all(out.qd == 0.0)
    z_halt = fk(core.arm, sim.q)[2, 3]
    assert z0 - z_halt > 0.03                              # it did come down before halting

    def up(core, t):
        core.on_twist(t, t, [0.0, 0.0, 0.03], [0.0, 0.0, 0.0], 'base_link')

    for _ in range(100):
        sim.tick(up)
    assert fk(core.arm, sim.q)[2, 3] > z_halt + 0.02


@pytest.mark.parametrize('q0', [Q_AWAY, np.zeros(6)], ids=['away', 'home'])
def test_a_huge_twist_jogs_within_the_limits_and_the_tick_goes_on(q0):
    """1e308 m/s: NaN commands for ever (away) or a tick that raised (home) before."""
    core, sim = make()
    sim.q = np.array(q0, dtype=float)
    sim.tick()

    def huge(core, t):
        core.on_twist(t, t, [1e300, 1e308, -1e300], [1e300, 1e307, 1e300], 'base_link')

    for _ in range(100):
        out = sim.tick(huge)
        assert out.state == sm.JOGGING, core.status().message
        assert np.all(np.isfinite(out.qd)) and np.all(np.isfinite(out.jog))
        assert np.all(np.abs(out.qd) <= core.arm.velocity_limits * (1.0 + 1e-12))
    assert np.any(sim.log[-1][2])                           # it does move
    while sim.tick().state == sm.JOGGING:
        assert sim.t < 5.0
    assert core.status().values['result'] == 'jog_stopped'


class RaisingGuard:
    """A collision guard whose veto raises: an exception inside a tick (test double)."""

    def __init__(self):
        self.calls = 0

    def __call__(self, plan):
        pass

    def veto(self, q, q_ahead):
        self.calls += 1
        raise RuntimeError('veto broke')


def test_an_exception_in_a_tick_is_a_fault_with_the_reason_that_fresh_states_clear():
    core, sim = make()
    for _ in range(30):
        sim.tick(twist_x)
    core.collision_guard = RaisingGuard()
    out = sim.tick(twist_x)                                 # raised out of tick() before
    assert out.state == sm.FAULT and not np.any(out.qd) and not np.any(out.jog)
    status = core.status()
    assert status.level == 'ERROR'
    assert status.message == 'tick failed: RuntimeError: veto broke'
    assert status.values['result'] == 'fault' and 'veto broke' in status.values['reason']
    assert core.tick_failures == 1
    core.collision_guard = None
    out = sim.tick()                                        # a fresh state: recovered
    assert out.state == sm.IDLE and core.tick_failures == 0
    sim.tick(twist_x)
    assert core.state == sm.JOGGING


def test_a_non_finite_command_is_a_fault_and_never_sent(monkeypatch):
    """Whatever law makes a NaN (the servo did, from a 1e308 twist), zero goes out instead."""
    core, sim = make()
    real = jogging.servo_step

    def nan_step(*args):
        out = real(*args)
        return replace(out, qd=np.full_like(out.qd, np.nan))

    for _ in range(10):
        sim.tick(twist_x)
    monkeypatch.setattr(jogging, 'servo_step', nan_step)
    out = sim.tick(twist_x)
    assert out.state == sm.FAULT
    assert np.array_equal(out.qd, np.zeros(6)) and np.array_equal(out.jog, np.zeros(6))
    assert np.array_equal(core.robot.commanded, np.zeros(6))
    assert core.status().message.startswith('non-finite command [nan')
    assert 'while jogging: not sent' in core.status().message
    monkeypatch.setattr(jogging, 'servo_step', real)
    assert sim.tick().state == sm.IDLE


def test_a_future_stamp_is_refused_and_the_jog_stops_on_time():
    """The last command stamped 1 s ahead kept the arm moving 1.31 s; now it stops in time."""
    core, sim = make()
    for _ in range(50):
        sim.tick(lambda c, t: c.on_joint_jog(t, t, ['joint1'], [0.2]))
    last = sim.t - DT
    with pytest.raises(InvalidInputError, match='in the future'):
        core.on_joint_jog(sim.t, sim.t + 1.0, ['joint1'], [0.2])
    assert 'in the future' in core.status().values['jog_refused']
    while sim.tick().state == sm.JOGGING:
        assert sim.t < 5.0
    stopped = next(t for t, state, qd in sim.log if t > last and not np.any(qd))
    timeout, a_max = core.config.servo.command_timeout, core.config.servo.a_max
    assert stopped - last <= timeout + 0.2 / a_max + 2 * DT


def test_a_stamp_slightly_ahead_goes_stale_by_its_arrival():
    """Within the tolerance it is taken, and ages from its arrival, not from its stamp."""
    core, sim = make()
    for _ in range(20):
        sim.tick(lambda c, t: c.on_joint_jog(t, t, ['joint1'], [0.2]))
    arrival = sim.t
    sim.tick(lambda c, t: c.on_joint_jog(t, t + 0.04, ['joint1'], [0.2]))
    while not core.status().values.get('jog_reason', '').startswith('commands stale'):
        sim.tick()
        assert sim.t < 1.0
    assert sim.t - DT <= arrival + core.config.servo.command_timeout + DT
