"""
The parts ``ControllerCore`` is built from, each built alone from its constructor's arguments.

A part takes what it needs (the arm, the robot, the ``CoreState`` record, the driver
compensation); these tests give it exactly that, set the record as a moment of a run would have
it, and check what the part does to it, without a core around it.
"""

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig, derive_config
from mover6_control.control.core_settings import CoreSettings
from mover6_control.control.core_state import CoreState
from mover6_control.control.driver_compensation import DriverCompensation
from mover6_control.control.jogging import Jogging, JogSession
from mover6_control.control.motion_plan import plan_stop
from mover6_control.control.motion_ticks import MotionTicks
from mover6_control.control.robot import Robot
from mover6_control.control.states_check import StatesCheck
from mover6_control.control.status import StatusKey as K
from mover6_control.control.status_report import StatusReport
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest

ARM = mover6()


def parts(config=None):
    """Return a robot at rest, measured at t = 0, and a fresh ``CoreState`` for ``config``."""
    robot = Robot.from_arm(ARM)
    robot.measure(0.0, ARM.joint_names, np.zeros(6), np.zeros(6))
    return robot, CoreState(derive_config(ARM, config or ControllerConfig()))


def test_core_state_steps_the_state_machine_and_marks_the_status_changed():
    _, shared = parts()
    shared.changed = False
    shared.step(sm.STATES_VALID, 'OK', 'joint states received; idle')
    assert (shared.state, shared.level, shared.message) == (sm.IDLE, 'OK',
                                                            'joint states received; idle')
    assert shared.changed
    assert shared.config is shared.derived.config


def test_settings_apply_now_when_idle_and_after_the_motion_when_moving():
    robot, shared = parts()
    settings = CoreSettings(ARM, robot, DriverCompensation(6), shared)
    shared.state = sm.IDLE
    assert settings.reconfigure(ControllerConfig(goal_tolerance=0.004))
    np.testing.assert_allclose(robot.goal_tolerances, 0.004)
    shared.state = sm.EXECUTING
    assert not settings.reconfigure(ControllerConfig(goal_tolerance=0.003))
    assert settings.pending_config.goal_tolerance == 0.003
    settings.apply_pending()                      # still moving: nothing yet
    np.testing.assert_allclose(robot.goal_tolerances, 0.004)
    shared.state = sm.IDLE
    settings.apply_pending()
    np.testing.assert_allclose(robot.goal_tolerances, 0.003)
    assert settings.pending_config is None and shared.config.goal_tolerance == 0.003


def test_settings_refuse_a_config_that_does_not_fit_and_change_nothing():
    robot, shared = parts()
    settings = CoreSettings(ARM, robot, DriverCompensation(6), shared)
    before = shared.derived
    with pytest.raises(InvalidInputError):
        settings.reconfigure(ControllerConfig(jog_units='fraction_of_max',
                                              driver_tick_size=(0.001,) * 5))
    assert shared.derived is before and shared.pending is None


def test_states_check_leaves_the_wait_faults_on_stale_states_and_recovers_on_newer_ones():
    robot, shared = parts()
    check = StatesCheck(robot, shared)
    check.check(0.01)
    assert shared.state == sm.IDLE
    shared.state = sm.EXECUTING                   # a motion runs when the states stop coming
    robot.give(plan_stop(np.zeros(6), np.full(6, 0.1), 1.0), 0.0)
    check.check(1.0)
    assert shared.state == sm.FAULT and shared.t_fault == 1.0
    assert shared.result[K.RESULT] == 'fault' and robot.plan is None
    check.check(1.1)                              # the same old states: still in fault
    assert shared.state == sm.FAULT
    robot.measure(1.2, ARM.joint_names, np.zeros(6), np.zeros(6))
    check.check(1.2)
    assert shared.state == sm.IDLE and 'again' in shared.message


def test_motion_ticks_stop_to_rest_then_hold():
    robot, shared = parts()
    ticks = MotionTicks(robot, shared, DriverCompensation(6))
    shared.state, shared.motion_id = sm.STOPPING, 7
    robot.give(plan_stop(np.zeros(6), np.full(6, 0.2), 1.0), 0.0)
    qd = ticks.stopping(0.01)
    assert np.all(np.abs(qd) < 0.2) and np.all(qd > 0.0)
    assert ticks.stopping(robot.plan.duration + 0.01) is None
    assert shared.state == sm.IDLE and robot.plan is None
    assert shared.message == 'motion 7 stopped: at rest, holding'


def test_jogging_refuses_while_a_motion_runs_and_keeps_the_reason_for_the_status():
    robot, shared = parts()
    jogging = Jogging(ARM, robot, shared)
    shared.state, shared.message = sm.EXECUTING, 'motion 1: executing'
    with pytest.raises(InvalidInputError, match='stop the motion first'):
        jogging.on_joint_jog(0.0, 0.0, ['joint1'], [0.1])
    assert 'jogging refused while executing' in jogging.session.refused
    shared.state = sm.IDLE
    jogging.on_joint_jog(0.0, 0.0, ['joint1'], [0.1])
    assert shared.state == sm.JOGGING and jogging.session.refused == ''
    qd = jogging.tick(0.01)
    assert qd[0] > 0.0 and not np.any(qd[1:])


def test_status_report_reads_the_record_and_the_jog_session():
    robot, shared = parts()
    session = JogSession(refused='jog command older than the timeout')
    report = StatusReport(ARM, robot, shared, session)
    shared.state, shared.motion_id = sm.IDLE, 3
    shared.pending = derive_config(ARM, ControllerConfig(position_gain=3.0))
    status = report.status()
    assert status.state == sm.IDLE and status.values[K.MOTION_ID] == 3
    assert status.values[K.PENDING_PARAMETERS] == 'position_gain 3.0'
    assert status.values[K.JOG_REFUSED] == 'jog command older than the timeout'
    assert status.values[K.TRACKING_ERROR] == '0.000000'
