"""The console's page logic without a browser: goal convention, routes, Plan, held jogs."""

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import pose_error
from mover6_control.nodes.console.page_logic import (GoalConvention, GoalRoute, JogHold,
                                                     Preview)
from mover6_control.tools.goal_convention import goal_from_pose, pose_from_goal
import numpy as np
import pytest

ARM = mover6()
CONVENTION = GoalConvention(ARM)


@pytest.mark.parametrize('numbers', [(0.30, 0.05, 0.36, 0.0, 0.0, 0.0),
                                     (0.1, 0.1, 0.2, 0.0, 1.5708, 0.0),
                                     (0.32, -0.03, 0.36, 0.3, -0.2, 0.5)])
def test_the_page_takes_goals_as_the_goal_command_does(numbers):
    T = CONVENTION.pose(numbers)
    assert np.allclose(T, pose_from_goal(ARM, *numbers))
    assert np.allclose(CONVENTION.numbers(T, numbers[3:]), goal_from_pose(ARM, T, ref=numbers[3:]))
    assert np.allclose(CONVENTION.numbers(T, numbers[3:]), numbers, atol=1e-9)


def test_zero_angles_keep_the_home_orientation():
    T = CONVENTION.pose((0.345, 0.0, 0.4425, 0.0, 0.0, 0.0))
    assert max(pose_error(T, fk(ARM, np.zeros(6)))) < 1e-6


@pytest.mark.parametrize('numbers', [(0.3, 0.0, 0.3, 0.0, 0.0), (0.3, 0.0, 0.3, 0, 0, np.nan),
                                     ('x', 0, 0, 0, 0, 0)])
def test_a_goal_that_is_not_six_finite_numbers_is_refused(numbers):
    with pytest.raises(InvalidInputError):
        CONVENTION.pose(numbers)


@pytest.mark.parametrize('shape, vias, route', [
    ('linear', 0, ('pose', 'pose_goal/linear')), ('joint', 0, ('pose', 'pose_goal/joint')),
    ('parabolic', 0, ('pose', 'pose_goal/parabolic')),
    ('parabolic', 1, ('path', 'path_goal/parabolic')), ('spline', 3, ('path', 'path_goal/spline')),
    ('arc', 1, ('path', 'path_goal/arc')), ('joint', 1, ('path', 'path_goal/joint'))])
def test_each_shape_goes_to_its_planner_topic(shape, vias, route):
    got = GoalRoute.of(shape, vias)
    assert (got.kind, got.topic) == route


@pytest.mark.parametrize('shape, vias', [('spline', 0), ('arc', 0), ('arc', 2), ('linear', 1),
                                         ('joint', 2), ('parabolic', 2), ('circle', 0)])
def test_a_shape_that_does_not_fit_its_vias_is_refused(shape, vias):
    with pytest.raises(InvalidInputError):
        GoalRoute.of(shape, vias)


def test_plan_gives_the_tool_path_to_the_goal():
    T = CONVENTION.pose((0.30, -0.08, 0.32, 0.0, 0.0, 0.0))
    answer = Preview(ARM).plan(np.zeros(6), 'linear', T)
    assert answer.planned and answer.closest_q is None
    assert np.allclose(answer.path[0], fk(ARM, np.zeros(6))[:3, 3], atol=1e-6)
    assert np.linalg.norm(answer.path[-1] - T[:3, 3]) < 1e-3
    # A straight line: every point on the segment from start to goal.
    start, end = answer.path[0], answer.path[-1]
    u = (end - start) / np.linalg.norm(end - start)
    off = [np.linalg.norm((p - start) - np.dot(p - start, u) * u) for p in answer.path]
    assert max(off) < 1e-3


def test_plan_of_a_path_goal_passes_its_via():
    via = CONVENTION.pose((0.32, -0.03, 0.36, 0.0, 0.0, 0.0))
    T = CONVENTION.pose((0.29, 0.10, 0.35, 0.0, 0.0, 0.0))
    answer = Preview(ARM).plan(np.zeros(6), 'spline', T, [via])
    assert answer.planned
    assert np.min(np.linalg.norm(answer.path - via[:3, 3], axis=1)) < 0.01


def test_a_refused_plan_says_why_and_gives_a_reachable_closest_pose():
    T = CONVENTION.pose((0.90, 0.0, 0.40, 0.0, 0.0, 0.0))
    answer = Preview(ARM).plan(np.zeros(6), 'linear', T)
    assert not answer.planned and answer.reason == 'out_of_reach'
    assert 'out_of_reach' in answer.text
    q = answer.closest_q
    assert q is not None and not ARM.limit_violations(q)


def test_the_line_gives_the_farthest_reachable_pose():
    preview = Preview(ARM)
    T = CONVENTION.pose((0.90, 0.0, 0.40, 0.0, 0.0, 0.0))
    q = preview.closest_on_line(np.zeros(6), T)
    reach = np.linalg.norm(fk(ARM, q)[:3, 3] - T[:3, 3])
    assert 0.0 < reach < np.linalg.norm(fk(ARM, np.zeros(6))[:3, 3] - T[:3, 3])


def test_a_held_jog_lasts_while_given_then_one_zero_then_nothing():
    hold = JogHold(6, 0.5)
    assert hold.due(0.0) is None
    hold.give([0.1, 0, 0, 0, 0, 0], 10.0)
    assert np.allclose(hold.due(10.4), [0.1, 0, 0, 0, 0, 0])
    hold.give([0.2, 0, 0, 0, 0, 0], 10.4)
    assert np.allclose(hold.due(10.8), [0.2, 0, 0, 0, 0, 0])      # given again: still held
    assert np.allclose(hold.due(10.9), np.zeros(6))                 # released: stop
    assert hold.due(11.0) is None


def test_release_stops_at_once_and_bad_commands_are_refused():
    hold = JogHold(6, 0.5)
    hold.give([0, 0.1, 0, 0, 0, 0], 0.0)
    hold.release()
    assert np.allclose(hold.due(0.1), np.zeros(6))
    for bad in ([np.inf, 0, 0, 0, 0, 0], [0.1, 0.2]):
        with pytest.raises(InvalidInputError):
            hold.give(bad, 0.2)
    assert hold.due(0.3) is None
