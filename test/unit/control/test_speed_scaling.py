"""Speed scaling in the ROS-free controller: the path kept, the velocity ramped, pause, resume."""

import math

from core_testing import send_demand
from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.profiles import LawConfig
from mover6_control.control.speed_scaling import check_factor, MAX_FACTOR, SpeedScaling
from mover6_control.control.status import MotionResult, StatusKey
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest
from test_controller_core import DT, Sim

GOAL = np.array([0.6, -0.4, 0.5, 0.3, -0.5, 0.7])
A_MAX = LawConfig().a_max
# Rounding of the per-tick bound: the path's acceleration is taken from the tick before.
ROUNDING = 1e-3


def make(profile='jerk_limited'):
    core = ControllerCore(mover6('hardware'), ControllerConfig(law=LawConfig(profile=profile)))
    return core, Sim(core)


def feedforward(core):
    return core.robot.reference[1].copy()


def run_logging(core, sim, until, log):
    """Tick until ``until(out)``; log the feedforward velocity and plan time of each tick."""
    def logged(out):
        if core.robot.reference is not None and out.state == sm.EXECUTING:
            log.append((sim.t, core.robot.plan_time, feedforward(core), sim.q.copy()))
        return until(out)
    return sim.run_until(logged)


@pytest.mark.parametrize('bad', [-0.1, 1.0 + 1e-9, math.nan, math.inf, -math.inf, 'fast', None])
def test_a_bad_factor_is_refused_naming_it_and_the_last_one_stays(bad):
    core, _ = make()
    core.request_speed_scaling(0.4)
    with pytest.raises(InvalidInputError, match='speed scaling factor'):
        core.request_speed_scaling(bad)
    assert core.speed_scaling.target == 0.4
    assert core.status().values[StatusKey.SPEED_SCALING_INPUT] == '0.400'


def test_the_bounds_are_taken():
    assert check_factor(0) == 0.0 and check_factor(MAX_FACTOR) == MAX_FACTOR


def test_factor_one_runs_the_plan_in_its_own_time():
    core, sim = make()
    sim.run_until(lambda out: out.state == sm.IDLE)
    send_demand(core, sim.t, GOAL[None, :])
    sim.run_until(lambda out: core.robot.plan_time > 0.5)
    last_tick = sim.t - DT
    assert core.robot.plan_time == pytest.approx(last_tick - core.robot.t_plan, abs=1e-9)


def test_slowed_paused_and_resumed_the_path_is_kept_and_the_velocity_ramps():
    core, sim = make()
    sim.run_until(lambda out: out.state == sm.IDLE)
    send_demand(core, sim.t, GOAL[None, :])
    plan = core.plan
    log = []
    run_logging(core, sim, lambda out: core.robot.plan_time > 0.3 * plan.duration, log)
    core.request_speed_scaling(0.3)
    run_logging(core, sim, lambda out: core.robot.plan_time > 0.5 * plan.duration, log)
    assert core.status().values[StatusKey.SPEED_SCALING] == '0.300'
    core.request_speed_scaling(0.0)
    paused_at = sim.t
    run_logging(core, sim, lambda out: core.speed_scaling.factor == 0.0, log)
    stopped_after = sim.t - paused_at
    tau_stop = core.robot.plan_time
    for _ in range(100):                       # held: the plan time and the arm stand still
        sim.tick()
    assert core.robot.plan_time == tau_stop and core.state == sm.EXECUTING
    assert np.allclose(feedforward(core), 0.0)
    assert np.allclose(sim.q, plan.sample(tau_stop)[0], atol=1e-3)
    core.request_speed_scaling(1.0)
    run_logging(core, sim, lambda out: out.state != sm.EXECUTING, log)
    sim.run_until(lambda out: out.state == sm.IDLE)
    assert core.status().values[StatusKey.RESULT] == MotionResult.ARRIVED
    assert np.allclose(sim.q, GOAL, atol=core.config.goal_tolerance)
    # The velocity never changed faster than a_max allows.
    qd = np.array([row[2] for row in log])
    accel = np.abs(np.diff(qd, axis=0)) / DT
    assert accel.max() <= A_MAX * (1.0 + ROUNDING), accel.max()
    # The stop took about as long as a stop at a_max from the slowed speed.
    slowest_stop = max(np.max(np.abs(row[2])) for row in log if paused_at - DT <= row[0]
                       <= paused_at) / A_MAX
    assert stopped_after <= slowest_stop + 3 * DT
    # The arm stayed on the plan's path: every position is one the path passes.
    taus = np.linspace(0.0, plan.duration, 4000)
    path = plan.positions(taus)
    off = max(float(np.min(np.linalg.norm(path - row[3], axis=1))) for row in log)
    assert off < 2e-3, off


def test_a_factor_asked_for_at_rest_applies_to_the_next_motion():
    core, sim = make()
    sim.run_until(lambda out: out.state == sm.IDLE)
    core.request_speed_scaling(0.5)
    send_demand(core, sim.t, GOAL[None, :])
    duration = core.plan.duration
    t0 = sim.t
    sim.run_until(lambda out: out.state != sm.EXECUTING)
    assert sim.t - t0 == pytest.approx(2.0 * duration, abs=0.05)


def line(qd):
    """Return the sample of a path at constant velocity ``qd``."""
    qd = np.asarray(qd, dtype=float)
    return lambda tau: (qd * tau, qd)


def test_the_rate_of_the_factor_is_bound_by_the_path_speed():
    scaling = SpeedScaling(2, 1.0)
    scaling.request(0.0)
    # |ds * 0.5| <= 1.0 * 0.01 per tick: at most 0.02 a tick.
    tau, _, v = scaling.advance(0.0, 0.01, line([0.5, -0.2]))
    assert scaling.factor == pytest.approx(0.98)
    assert tau == pytest.approx(0.0098) and v == pytest.approx([0.49, -0.196])
    scaling.advance(tau, 0.01, line([0.0, 0.0]))
    assert scaling.factor == 0.0                # a still path puts no bound on it
    assert scaling.paused


def test_a_tick_of_no_time_changes_nothing():
    scaling = SpeedScaling(1, 1.0, initial=0.5)
    scaling.request(1.0)
    assert scaling.advance(0.2, 0.0, line([1.0]))[0] == 0.2 and scaling.factor == 0.5
