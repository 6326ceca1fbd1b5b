"""
The goal CLI's reading of X Y Z A B C: as the Mover6 report (relative to home) or base frame.

The Mover6 report's MATLAB builds the goal rotation as ``tform2rotm(initial_Pos) *
eul2rotm([A B C])``; the CLI does the same unless ``--absolute`` is given.
"""

import warnings

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.ik_closed_form import ik_closed_form
from mover6_control.kinematics.reachability import check_pose
from mover6_control.kinematics.rotations import (euler_zyx_near, euler_zyx_to_matrix,
                                                 matrix_to_euler_zyx, pose_from_xyzabc)
from mover6_control.tools.goal_cli import run
from mover6_control.tools.goal_convention import (EXIT_ARRIVED, EXIT_NO_NODES, EXIT_REFUSED,
                                                  format_numbers, format_outcome, goal_from_pose,
                                                  home_pose, Outcome, pose_from_goal,
                                                  poses_from_numbers)
from mover6_control.tools.goal_parser import build_parser
from mover6_control.values import ToolPose
import numpy as np
import pytest

ARM = mover6()
LINEAR_EXAMPLE = (0.445, 0.0, 0.4425, 0.0, 0.0, 0.0)
LINEAR_EXAMPLE_Q = np.array([0.0, 0.614, -0.735, 0.0, 0.121, 0.0])
IK_EXAMPLE = (0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)
IK_EXAMPLE_Q = np.array([-0.785, -0.907, 1.296, 0.0, 1.181, 0.785])


def test_home_orientation_comes_from_the_arm_model():
    T = home_pose(ARM)
    np.testing.assert_allclose(T[:3, 3], [0.345, 0.0, 0.4425], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], euler_zyx_to_matrix(0.0, np.pi / 2, 0.0), atol=1e-9)


def test_linear_example_keeps_the_home_orientation():
    (T,) = poses_from_numbers(list(LINEAR_EXAMPLE), quat=False)
    np.testing.assert_allclose(T[:3, 3], [0.445, 0.0, 0.4425], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], fk(ARM, np.zeros(6))[:3, :3], atol=1e-12)
    verdict = check_pose(ARM, T)
    assert verdict.reachable
    np.testing.assert_allclose(verdict.q, LINEAR_EXAMPLE_Q, atol=1e-3)


def test_ik_example_has_one_closed_form_solution_within_90_deg_the_reports():
    T = pose_from_goal(ARM, *IK_EXAMPLE)
    sols = ik_closed_form(ARM, T, within_limits=True)
    assert sols.shape == (1, 6), sols
    np.testing.assert_allclose(sols[0], IK_EXAMPLE_Q, atol=1e-3)


def test_absolute_is_the_base_frame_reading():
    for numbers in (IK_EXAMPLE, (0.30, -0.08, 0.32, 0.4, -0.2, 1.0)):
        (T,) = poses_from_numbers(list(numbers), quat=False, absolute=True)
        np.testing.assert_allclose(T, pose_from_xyzabc(*numbers), atol=1e-15)


def test_old_absolute_home_orientation_is_new_zero():
    old = pose_from_goal(ARM, 0.30, 0.05, 0.36, 0.0, 1.5708, 0.0, absolute=True)
    new = pose_from_goal(ARM, 0.30, 0.05, 0.36, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(new, old, atol=1e-5)


def test_path_numbers_use_the_same_convention():
    numbers = [0.32, -0.03, 0.36, 0.0, 0.0, 0.0, 0.29, 0.10, 0.35, 0.1, 0.0, 0.0]
    poses = poses_from_numbers(numbers, quat=False)
    assert len(poses) == 2 and all(isinstance(T, ToolPose) for T in poses)
    np.testing.assert_allclose(poses[1], pose_from_goal(ARM, *numbers[6:]), atol=1e-15)


@pytest.mark.parametrize('absolute', (False, True))
@pytest.mark.parametrize('numbers', (LINEAR_EXAMPLE, IK_EXAMPLE,
                                     (0.3, 0.0, 0.3, 0.2, 1.5708, -0.1),
                                     (0.3, 0.0, 0.3, 0.5, -np.pi / 2, 0.2),
                                     (0.3, 0.0, 0.3, 0.3, -0.4, 2.0)))
def test_reached_pose_prints_back_as_typed(numbers, absolute):
    T = pose_from_goal(ARM, *numbers, absolute=absolute)
    back = goal_from_pose(ARM, T, absolute, ref=numbers[3:])
    # Within 1e-3 rad of gimbal lock B prints as exactly +-pi/2: the same to 4 decimals.
    assert format_numbers(back) == format_numbers(numbers)
    np.testing.assert_allclose(pose_from_goal(ARM, *back, absolute=absolute), T, atol=1e-5)


def test_pitch_of_half_pi_gives_no_warning_and_a_deterministic_split():
    R = euler_zyx_to_matrix(0.3, np.pi / 2, 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        a, b, c = matrix_to_euler_zyx(R)
        near = euler_zyx_near(R, (0.3, np.pi / 2, 0.1))
    assert (a, b, c) == matrix_to_euler_zyx(R.copy())
    assert b == pytest.approx(np.pi / 2) and c == 0.0 and a == pytest.approx(0.2)
    np.testing.assert_allclose(euler_zyx_to_matrix(a, b, c), R, atol=1e-12)
    np.testing.assert_allclose(near, (0.3, np.pi / 2, 0.1), atol=1e-12)
    R = euler_zyx_to_matrix(0.3, -np.pi / 2, 0.1)
    a, b, c = matrix_to_euler_zyx(R)
    assert b == pytest.approx(-np.pi / 2) and c == 0.0 and a == pytest.approx(0.4)


def test_euler_round_trip_everywhere():
    rng = np.random.default_rng(7)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for _ in range(500):
            angles = rng.uniform(-np.pi, np.pi, 3)
            angles[1] /= 2.0
            R = euler_zyx_to_matrix(*angles)
            np.testing.assert_allclose(euler_zyx_to_matrix(*matrix_to_euler_zyx(R)), R,
                                       atol=1e-12)
            ref = rng.uniform(-np.pi, np.pi, 3)
            np.testing.assert_allclose(euler_zyx_to_matrix(*euler_zyx_near(R, ref)), R,
                                       atol=1e-12)


def test_parser_takes_absolute_in_the_plain_form_and_on_paths():
    args = build_parser().parse_args(['pose', '0.4', '0', '0.4', '0', '1.5708', '0',
                                      '--absolute'])
    assert args.absolute
    args = build_parser().parse_args(['path', '0.4', '0', '0.4', '0', '0', '0'])
    assert not args.absolute
    assert '--absolute' in build_parser().format_help()
    assert 'R_home' in build_parser().format_help()


def test_result_line_gives_the_reached_pose_in_the_goals_convention():
    T = pose_from_goal(ARM, *LINEAR_EXAMPLE)
    outcome = Outcome(EXIT_ARRIVED, 'arrived', duration=1.0, reached_pose=T,
                      final_position_error=0.0)
    line = format_outcome(outcome, (ARM, False, (0.0, 0.0, 0.0)))
    assert line.startswith('RESULT arrived')
    assert line.endswith('reached X Y Z A B C from home: 0.4450 0.0000 0.4425 0.0000 0.0000 '
                         '0.0000')
    line = format_outcome(outcome, (ARM, True, (0.0, 1.5708, 0.0)))
    assert line.endswith('0.4450 0.0000 0.4425 0.0000 1.5708 0.0000')
    refused = Outcome(EXIT_REFUSED, 'goal refused (joint_limits)',
                      closest_pose_xyzabc='0.4450 0.0000 0.4425 0.0000 1.5708 0.0000')
    line = format_outcome(refused, (ARM, False, (0.0, 0.0, 0.0)))
    assert 'closest pose inside the joint limits' in line
    assert line.endswith('0.4450 0.0000 0.4425 0.0000 0.0000 0.0000')


class FakeClient:
    """Stands in for GoalClient: records the poses sent, 'arrives' exactly at the goal."""

    arm = ARM

    def __init__(self):
        self.sent = []

    def wait_ready(self, **kwargs):
        return None

    def set_planner_parameters(self, params):
        return None

    def send_pose(self, T, frame_id='base_link', **kwargs):
        self.sent.append(T)
        return Outcome(EXIT_ARRIVED, 'arrived', reached_pose=T, final_position_error=0.0)

    def send_path(self, poses, frame_id='base_link', **kwargs):
        self.sent.append(poses)
        return Outcome(EXIT_ARRIVED, 'arrived', reached_pose=poses[-1], final_position_error=0.0)


@pytest.mark.parametrize('argv, absolute', (
    (['0.1', '0.1', '0.2', '0', '1.5708', '0'], False),
    (['pose', '0.1', '0.1', '0.2', '0', '1.5708', '0', '--absolute'], True),
    (['path', '--via', '0.3', '0', '0.3', '0', '0', '0', '0.1', '0.1', '0.2', '0', '1.5708', '0'],
     False)))
def test_run_sends_the_goal_and_prints_it_back(argv, absolute):
    client, lines = FakeClient(), []
    assert run(argv, client, out=lines.append) == EXIT_ARRIVED
    sent = client.sent[0] if argv[0] != 'path' else client.sent[0][-1]
    np.testing.assert_allclose(sent, pose_from_goal(ARM, *IK_EXAMPLE, absolute=absolute),
                               atol=1e-15)
    assert lines[-1].endswith('0.1000 0.1000 0.2000 0.0000 1.5708 0.0000'), lines


class StopClient(FakeClient):
    """A client whose controller ~/stop service is there or not (``available``)."""

    def __init__(self, available):
        super().__init__()
        self.available = available

    def stop(self, timeout=10.0):
        if not self.available:
            return False, 'the controller stop service is not available', False
        return True, 'stopping', True


def test_stop_exit_codes_follow_the_readme():
    """'goal stop': 0 when stopped, 3 (the nodes are not there) without a controller."""
    lines = []
    assert run(['stop'], StopClient(True), out=lines.append) == EXIT_ARRIVED
    assert run(['stop'], StopClient(False), out=lines.append) == EXIT_NO_NODES
    assert lines[-1].startswith('RESULT failed: the controller stop service is not available')


def test_help_lists_jog():
    """The keyboard jogging command is among the commands --help lists."""
    assert 'jog' in build_parser().format_help()
