"""Jogging in the controller core: the state machine shared with motions, reasons on status."""

from mover6_control.control import state_machine as sm
from mover6_control.control.collision_guard import CollisionGuard
from mover6_control.control.controller_core import (config_changes, ControllerConfig,
                                                    ControllerCore)
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
        self.core.on_joint_states(self.t, self.q)
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
    core.on_demands(sim.t, [GOAL])
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
    core.on_demands(sim.t, [GOAL])
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
