"""The ROS-free controller driven with synthetic time and a simulated arm (no sleeps, no ROS)."""

import importlib.util

from core_testing import send_demand, send_states, send_states_lacking
from hypothesis import assume, given, settings
import hypothesis.strategies as st
from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.profiles import LawConfig
from mover6_control.control.status import Cause
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest

DT = 0.01
HAS_TIMING = importlib.util.find_spec('mover6_control.motion.timing.time_optimal') is not None
PROFILES = ['synchronised', 'trapezoidal', 'jerk_limited'] + (
    ['continuous'] if HAS_TIMING else [])
GOAL = np.array([0.4, -0.3, 0.2, 0.3, -0.2, 0.5])


class Sim:
    """An arm that integrates the commanded velocity and reports its state every tick."""

    def __init__(self, core, q0=None, follow=True):
        self.core = core
        self.q = np.zeros(6) if q0 is None else np.array(q0, dtype=float)
        self.t = 0.0
        self.follow = follow
        self.log = []       # (t, state, qd)
        self.report = True

    def tick(self):
        if self.report:
            send_states(self.core, self.t, self.q)
        out = self.core.tick(self.t)
        self.log.append((self.t, out.state, out.qd.copy()))
        if self.follow:
            self.q = self.q + out.qd * DT
        self.t = round(self.t + DT, 9)
        return out

    def run_until(self, predicate, limit=30.0):
        while self.t < limit:
            out = self.tick()
            if predicate(out):
                return out
        raise AssertionError(f'condition not met by t={self.t}; state {self.core.state}')


def make(profile='trapezoidal', arm=None, **kw):
    law = LawConfig(profile=profile, **kw.pop('law', {}))
    core = ControllerCore(arm or mover6('hardware'), ControllerConfig(law=law, **kw))
    return core, Sim(core)


def test_waits_for_states_and_commands_zero():
    core, sim = make()
    out = core.tick(0.0)
    assert out.state == sm.WAITING_FOR_STATES and not np.any(out.qd)
    with pytest.raises(InvalidInputError, match='waiting_for_states'):
        send_demand(core, 0.0, GOAL[None])
    send_states_lacking(core, 0.0, 'joint6')
    assert core.tick(0.0).state == sm.WAITING_FOR_STATES
    assert 'joint6' in core.status().message
    sim.tick()
    assert core.state == sm.IDLE


@pytest.mark.parametrize('profile', PROFILES)
def test_every_profile_arrives_with_explicit_zero(profile):
    core, sim = make(profile)
    sim.tick()
    Q = np.array([[0.2, 0.1, 0.0, 0.1, 0.0, 0.2], GOAL])
    assert send_demand(core, sim.t, Q) == 1
    out = sim.run_until(lambda o: o.state == sm.IDLE)
    assert not np.any(out.qd)                      # the tick entering idle sends zeros
    status = core.status()
    assert status.level == 'OK' and status.values['result'] == 'arrived'
    assert float(status.values['final_joint_error']) <= 0.002
    assert status.values['waypoint'] == 2 and status.values['waypoints'] == 2
    assert status.values['motion_id'] == 1
    np.testing.assert_allclose(sim.q, GOAL, atol=0.002)
    speeds = np.array([qd for _, _, qd in sim.log])
    assert np.all(np.abs(speeds) <= core.arm.velocity_limits * (1 + 1e-9))
    assert send_demand(core, sim.t, GOAL[None]) == 2


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-0.7, 0.7), min_size=6, max_size=6),
       st.lists(st.floats(-0.7, 0.7), min_size=6, max_size=6))
def test_synchronised_joints_finish_within_one_tick(q0, q1):
    core = ControllerCore(mover6('hardware'),
                          ControllerConfig(law=LawConfig(profile='synchronised')))
    moving = np.abs(np.subtract(q1, q0)) > 0.01
    assume(moving.any())                  # a move: a demand with no joint to time is not one
    sim = Sim(core, q0)
    sim.tick()
    send_demand(core, sim.t, [q1])
    sim.run_until(lambda o: o.state != sm.EXECUTING)
    speeds = np.abs(np.array([qd for _, state, qd in sim.log if state == sm.EXECUTING]))
    assert speeds.size > 0, f'the controller never executed the demand: {sim.log[-3:]}'
    peak = speeds.max(axis=0)
    finish = [np.nonzero(speeds[:, i] > 0.5 * peak[i])[0].max() for i in np.nonzero(moving)[0]]
    assert max(finish) - min(finish) <= 1


def test_trapezoid_peak_and_final_position_are_eq16_to_19():
    core, sim = make('trapezoidal', law={'t_max': 1.0}, position_gain=0.0)
    sim.tick()
    delta = np.array([0.3, -0.15, 0.0, 0.2, -0.1, 0.3])
    send_demand(core, sim.t, [delta])
    sim.run_until(lambda o: o.state == sm.IDLE)
    speeds = np.array([qd for _, _, qd in sim.log])
    v_max = np.abs(delta) / (1.0 - 0.25)                          # eq. 16, t_blend = t_max / 4
    np.testing.assert_allclose(np.max(np.abs(speeds), axis=0), v_max, rtol=1e-9)
    np.testing.assert_allclose(sim.q, delta, atol=0.002)         # eq. 19


def test_closed_loop_removes_drift():
    core, sim = make('trapezoidal', law={'t_max': 3.0}, position_gain=2.0)
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    worst = 0.0
    while core.state == sm.EXECUTING:
        sim.q[1] += 0.0005                       # a joint slipping at 0.05 rad/s while moving
        sim.tick()
        worst = max(worst, float(core.status().values['max_joint_error']))
    assert core.plan.duration > 2.0              # open loop would drift by more than 0.1 rad
    assert worst <= 0.05 / 2.0 + 0.002           # bounded by slip rate / gain
    sim.run_until(lambda o: o.state == sm.IDLE)
    assert core.status().values['result'] == 'arrived'


def test_stale_states_fault_within_one_tick_and_recover():
    core, sim = make('trapezoidal', state_timeout=0.25)
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.5)
    last = sim.t - DT
    sim.report = False                                            # the arm stops reporting
    out = sim.run_until(lambda o: o.state == sm.FAULT)
    assert sim.t - DT - last <= 0.25 + DT + 1e-9
    assert not np.any(out.qd) and out.status_changed
    status = core.status()
    assert status.level == 'ERROR' and status.values['result'] == 'fault'
    assert 'stale' in status.message
    assert not np.any(sim.tick().qd)                              # holds at zero
    with pytest.raises(InvalidInputError, match='fault'):
        send_demand(core, sim.t, [GOAL])
    sim.report = True
    out = sim.tick()
    assert out.state == sm.IDLE and not np.any(out.qd)


def test_invalid_states_fault_at_the_next_tick():
    core, sim = make()
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.3)
    send_states_lacking(core, sim.t, 'joint4')
    sim.report = False
    out = sim.tick()
    assert out.state == sm.FAULT and not np.any(out.qd)
    assert 'joint4' in core.status().message


@pytest.mark.parametrize('bad, reason', [
    (np.zeros(7), 'multiple of 6'),
    (np.zeros(0), 'empty'),
    (np.array([[0, 0, np.nan, 0, 0, 0]]), 'non-finite'),
    (np.array([[0, 0, 0, 0, 0, 3.0]]), 'joint6'),
    (np.array([[0, 0, 0, 0, 0, 0], [0, 1.2, 0, 0, 0, 0]]), 'waypoint 1'),
])
def test_bad_demands_leave_the_running_motion(bad, reason):
    core, sim = make()
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.3)
    plan = core.plan
    with pytest.raises(InvalidInputError, match=reason):
        send_demand(core, sim.t, bad)
    assert core.plan is plan and core.motion_id == 1 and core.state == sm.EXECUTING


def test_flat_demand_is_accepted():
    core, sim = make()
    sim.tick()
    assert send_demand(core, sim.t, np.concatenate([GOAL, GOAL])) == 1
    assert core.status().values['waypoints'] == 2


@pytest.mark.parametrize('profile', PROFILES)
def test_preemption_does_not_jump(profile):
    law = {'a_max': 1.0, 'j_max': 20.0}
    core, sim = make(profile, law=law)
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.8)
    before = sim.log[-1][2]
    assert np.max(np.abs(before)) > 0.2                           # really moving
    send_demand(core, sim.t, [-GOAL])
    after = sim.tick().qd
    assert core.state == sm.EXECUTING and core.motion_id == 2
    assert np.max(np.abs(after - before)) <= 2 * law['a_max'] * DT
    sim.run_until(lambda o: o.state == sm.IDLE)
    np.testing.assert_allclose(sim.q, -GOAL, atol=0.002)


def test_stop_decelerates_keeps_direction_and_holds():
    core, sim = make('trapezoidal', law={'a_max': 2.0})
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.8)
    before = sim.log[-1][2]
    ok, _ = core.request_stop(sim.t)
    assert ok and core.state == sm.STOPPING
    with pytest.raises(InvalidInputError, match='stopping'):
        send_demand(core, sim.t, [GOAL])
    out = sim.run_until(lambda o: o.state == sm.IDLE)
    assert not np.any(out.qd)
    ramp = np.array([qd for _, state, qd in sim.log if state == sm.STOPPING])
    assert np.all(np.diff(np.linalg.norm(ramp, axis=1)) <= 1e-12)
    for row in ramp:
        np.testing.assert_allclose(np.cross(row[:3], before[:3]), 0.0, atol=1e-9)
    assert np.max(np.abs(np.diff(np.vstack([before, ramp]), axis=0))) <= 2.0 * DT * 1.01
    assert core.status().values['result'] == 'stopped'
    assert not np.any(sim.tick().qd)


def test_arm_that_does_not_move_aborts_and_stops():
    core, sim = make('trapezoidal', path_tolerance=0.05)
    sim.follow = False
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    out = sim.run_until(lambda o: o.state == sm.IDLE)
    assert not np.any(out.qd)
    status = core.status()
    assert status.values['result'] == 'aborted' and 'path tolerance' in status.values['reason']
    assert status.values['cause'] == Cause.PATH_TOLERANCE    # what a reader decides on
    assert any(state == sm.STOPPING for _, state, _ in sim.log)


def test_settle_timeout_reports_aborted():
    core, sim = make('trapezoidal', settle_timeout=0.3, position_gain=0.0)
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > core.plan.duration - 0.1)
    sim.q[0] += 0.1                                               # pushed off the goal
    sim.run_until(lambda o: o.state == sm.IDLE)
    status = core.status()
    assert status.level == 'WARN' and status.values['result'] == 'aborted'
    assert status.values['cause'] == Cause.GOAL_TOLERANCE == 'goal_tolerance'


def test_never_commands_further_past_a_limit():
    arm = mover6('within_90_deg')
    core = ControllerCore(arm, ControllerConfig(law=LawConfig(profile='trapezoidal')))
    sim = Sim(core, q0=[0.0, 0.0, 0.0, 0.0, 0.0, arm.upper[5] + 0.02])
    sim.tick()
    send_demand(core, sim.t, [[0.3, 0, 0, 0, 0, arm.upper[5]]])
    for _ in range(200):
        q6 = sim.q[5]
        out = sim.tick()
        if q6 >= arm.upper[5]:
            assert out.qd[5] <= 0.0


def test_fraction_of_max_units_and_limits():
    core, sim = make('trapezoidal', jog_units='fraction_of_max', speed_override=0.25)
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 1.0)
    out = core.tick(sim.t)
    vlim = core.arm.velocity_limits
    np.testing.assert_allclose(out.jog, out.qd / (vlim * 0.25))
    speeds = np.array([qd for _, _, qd in sim.log])
    assert np.all(np.abs(speeds) <= 0.25 * vlim * (1 + 1e-9))


def test_reset_from_fault_waits_for_states():
    core, sim = make()
    sim.tick()
    sim.report = False
    sim.run_until(lambda o: o.state == sm.FAULT)
    core.reset(sim.t)
    assert core.state == sm.WAITING_FOR_STATES
    sim.report = True
    assert sim.tick().state == sm.IDLE


def test_bad_config_is_rejected():
    with pytest.raises(InvalidInputError, match='jog_units'):
        ControllerConfig(jog_units='furlongs')
    with pytest.raises(InvalidInputError, match='goal_tolerance'):
        ControllerConfig(goal_tolerance=0.0)
    with pytest.raises(InvalidInputError, match='state_timeout'):
        ControllerConfig(state_timeout=-1.0)


def test_prepared_demand_commits_later_without_a_jump():
    core, sim = make('jerk_limited', law={'a_max': 1.0, 'j_max': 20.0})
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > 0.8)
    pending = core.prepare_demand(sim.t, [-GOAL], core.snapshot())
    assert core.motion_id == 1 and core.plan is not pending.plan   # nothing changed yet
    for _ in range(5):                                               # ticks while planning
        sim.tick()
    assert core.is_current(pending)                                  # commit will not re-plan
    before = sim.log[-1][2]
    assert core.commit_demand(pending) == 2
    after = sim.tick().qd
    # The new plan left from the state at prepare time: the step grows with the planning delay
    # (5 ticks here) as a_max * delay at most, far below the reversal a cold switch would give.
    assert np.max(np.abs(after - before)) <= 1.0 * (5 + 2) * DT
    assert np.max(np.abs(before)) > 0.3
    sim.run_until(lambda o: o.state == sm.IDLE)
    np.testing.assert_allclose(sim.q, -GOAL, atol=0.002)


def test_prepared_demand_replans_when_the_motion_ended_meanwhile():
    core, sim = make('trapezoidal')
    sim.tick()
    send_demand(core, sim.t, [GOAL])
    sim.run_until(lambda o: sim.t > core.plan.duration - 0.05)
    pending = core.prepare_demand(sim.t, [np.zeros(6)], core.snapshot())
    assert core.is_current(pending)
    sim.run_until(lambda o: o.state == sm.IDLE)
    assert not core.is_current(pending)          # a node prepares it again, without its lock
    core.commit_demand(pending)
    assert core.plan is not pending.plan
    np.testing.assert_allclose(core.plan.sample(0.0)[0], sim.q)     # from where the arm is
    np.testing.assert_allclose(core.plan.sample(0.0)[1], 0.0)


def test_prepared_demand_is_stale_once_another_motion_started():
    core, sim = make('trapezoidal')
    sim.tick()
    pending = core.prepare_demand(sim.t, [GOAL], core.snapshot())
    assert core.is_current(pending)
    send_demand(core, sim.t, [-GOAL])            # another demand got in first
    assert not core.is_current(pending)
    assert core.commit_demand(pending) == 2
    assert core.is_current(core.prepare_demand(sim.t, [np.zeros(6)], core.snapshot()))


def test_prepared_demand_is_refused_after_a_fault():
    core, sim = make()
    sim.tick()
    pending = core.prepare_demand(sim.t, [GOAL], core.snapshot())
    sim.report = False
    sim.run_until(lambda o: o.state == sm.FAULT)
    with pytest.raises(InvalidInputError, match='fault'):
        core.commit_demand(pending)
    assert core.motion_id == 0


@pytest.mark.parametrize('profile', ['synchronised', 'trapezoidal', 'continuous'])
def test_arrival_waits_for_a_lagging_arm_and_it_stays_within_tolerance(profile):
    """
    A lagging arm is not declared arrived until it will stay within tolerance.

    The arm's velocity follows the command two ticks late (servo and transport lag, as the
    simulated arm) and the states report it; arrival is declared only once the arm will not
    coast out of the tolerance, and it stays in afterwards. (Before this check the
    synchronised law declared arrival at full speed and the arm coasted 5.5 mrad past.)
    """
    core, _ = make(profile)
    dt = 1.0 / core.config.rate
    goal = np.array([0.3, -0.2, 0.25, 0.1, -0.15, 0.2])
    q, t = np.zeros(6), 0.0
    pipeline = [np.zeros(6), np.zeros(6)]    # commands on their way to the joints
    send_states(core, t, q, np.zeros(6))
    core.tick(t)
    send_demand(core, t, goal[None])
    arrived_at = None
    for _ in range(3000):
        t += dt
        out = core.tick(t)
        pipeline.append(out.qd.copy())
        qd = pipeline.pop(0)      # the arm moves at the speed commanded two ticks ago
        q = q + qd * dt
        send_states(core, t, q, qd)
        if arrived_at is None and core.status().values.get('result') == 'arrived':
            arrived_at = t
        if arrived_at is not None:
            assert np.all(np.abs(q - goal) <= 0.002 + 1e-12), (t - arrived_at, q - goal)
            if t - arrived_at > 0.5:
                break
    assert arrived_at is not None, core.status().message


def test_reconfigure_when_idle_applies_at_once():
    core, sim = make('trapezoidal')
    sim.run_until(lambda out: out.state == sm.IDLE)
    new = ControllerConfig(law=LawConfig(profile='synchronised'), goal_tolerance=0.004,
                           rate=50.0)
    assert core.reconfigure(new) is True
    values = core.status().values
    assert values['profile'] == 'synchronised' and values['rate'] == '50'
    assert values['goal_tolerance'].split() == ['0.004000'] * 6
    assert 'pending_parameters' not in values
    send_demand(core, sim.t, GOAL)
    assert core.plan is not None and 'synchronised' in core.status().message


def test_reconfigure_during_a_motion_applies_when_it_ends():
    core, sim = make('trapezoidal')
    sim.run_until(lambda out: out.state == sm.IDLE)
    send_demand(core, sim.t, GOAL)
    sim.tick()
    new = ControllerConfig(law=LawConfig(profile='synchronised'))
    assert core.reconfigure(new) is False
    values = core.status().values
    assert values['profile'] == 'trapezoidal'
    assert values['pending_parameters'] == 'profile synchronised'
    assert core.pending_config is new
    plan = core.plan
    sim.run_until(lambda out: out.state == sm.IDLE)
    assert core.plan is plan or core.plan is None      # the running motion kept its plan
    values = core.status().values
    assert values['profile'] == 'synchronised' and 'pending_parameters' not in values
    assert core.pending_config is None and core.config is new


def test_reconfigure_that_does_not_fit_changes_nothing():
    core, sim = make('trapezoidal')
    sim.run_until(lambda out: out.state == sm.IDLE)
    before = core.config
    slow = ControllerConfig(jog_units='fraction_of_max', speed_override=0.01)
    with pytest.raises(InvalidInputError, match='speed_override'):
        core.check_config(slow)
    with pytest.raises(InvalidInputError, match='speed_override'):
        core.reconfigure(slow)
    assert core.config is before and core.pending_config is None


def test_prepared_demand_replans_when_the_config_changed_meanwhile():
    core, sim = make('trapezoidal')
    sim.run_until(lambda out: out.state == sm.IDLE)
    pending = core.prepare_demand(sim.t, GOAL[None, :], core.snapshot())
    core.reconfigure(ControllerConfig(law=LawConfig(profile='synchronised')))
    assert not core.is_current(pending)
    core.commit_demand(pending)
    assert core.plan is not pending.plan and 'synchronised' in core.status().message
