"""Cartesian pose paths: ends exact, shapes as the reports define them, SLERP, sampling, errors."""

from hypothesis import assume, given, settings
import hypothesis.strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import (euler_zyx_to_matrix, goal_relative_to_start,
                                                 make_transform, rotation_angle_between)
from mover6_control.motion import paths
import numpy as np
import pytest

R_HOME = euler_zyx_to_matrix(0.0, np.pi / 2, 0.0)
T0 = make_transform([0.345, 0.0, 0.4425], R_HOME)
T1 = make_transform([0.25, 0.15, 0.30], euler_zyx_to_matrix(0.4, 1.2, -0.3))


def angles_from(poses, R):
    return np.array([rotation_angle_between(R, T[:3, :3]) for T in poses])


def assert_valid_poses(poses):
    R = poses[:, :3, :3]
    assert np.allclose(np.einsum('nji,njk->nik', R, R), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(poses[:, 3], [0.0, 0.0, 0.0, 1.0])


def test_linear_path_mover6_report_eq4_and_slerp():
    poses = paths.linear_curve(T0, T1, n=20).poses
    assert poses.shape == (20, 4, 4)
    assert np.array_equal(poses[0], T0) and np.array_equal(poses[-1], T1)
    t = np.linspace(0.0, 1.0, 20)[:, None]
    assert np.allclose(poses[:, :3, 3], (1 - t) * T0[:3, 3] + t * T1[:3, 3])   # eq. 4
    total = rotation_angle_between(T0[:3, :3], T1[:3, :3])
    assert np.allclose(angles_from(poses, T0[:3, :3]), t[:, 0] * total, atol=1e-9)
    assert_valid_poses(poses)


def test_mover6_report_example_keeps_home_orientation():
    T_goal = goal_relative_to_start(T0, 0.445, 0.0, 0.4425, 0.0, 0.0, 0.0)
    assert np.allclose(T_goal[:3, :3], R_HOME)
    poses = paths.linear_curve(T0, T_goal, n=20).poses
    assert np.allclose(poses[:, :3, :3], R_HOME)
    assert np.allclose(np.diff(poses[:, 0, 3]), 0.1 / 19)


@pytest.mark.parametrize('max_step, max_angle_step', [(0.01, None), (None, 0.05), (0.02, 0.1)])
def test_linear_path_by_step_is_the_fewest_poses_within_the_steps(max_step, max_angle_step):
    poses = paths.linear_curve(T0, T1, max_step=max_step, max_angle_step=max_angle_step).poses
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    turns = np.array([rotation_angle_between(a[:3, :3], b[:3, :3])
                      for a, b in zip(poses[:-1], poses[1:])])
    if max_step:
        assert steps.max() <= max_step + 1e-12
    if max_angle_step:
        assert turns.max() <= max_angle_step + 1e-12
    fewer = len(poses) - 2                       # one step fewer would break a limit
    assert (max_step and steps.sum() / fewer > max_step) or \
        (max_angle_step and turns.sum() / fewer > max_angle_step)


def test_parabola_mover6_report_example():
    A, B = np.array([0.5, 0.2, 0.0]), np.array([0.9, 1.0, 2.0])
    M = (A + B) / 2 + [0.0, 0.0, 2.0]
    a, b, c = paths.parabola_coefficients(A, M, B)
    inv = np.linalg.inv([[0, 0, 1], [1, 1, 1], [0.25, 0.5, 1]])      # eq. 13-15
    for axis in range(3):
        assert np.allclose([a[axis], b[axis], c[axis]], inv @ [A[axis], B[axis], M[axis]])
    TA, TB = make_transform(A, R_HOME), make_transform(B, np.eye(3))
    poses = paths.parabolic_curve(TA, TB, 2.0, n=101).poses
    assert np.allclose(poses[50, :3, 3], M)                            # r(0.5) = M
    assert np.array_equal(poses[0], TA) and np.array_equal(poses[-1], TB)
    t = np.linspace(0.0, 1.0, 101)[:, None]
    assert np.allclose(poses[:, :3, 3], a * t ** 2 + b * t + c)        # eq. 11


def test_parabola_by_step_keeps_every_step():
    poses = paths.parabolic_curve(T0, T1, 0.1, max_step=0.005).poses
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    assert steps.max() <= 0.005 + 1e-12


@pytest.mark.parametrize('k', [0, 1, 3])
def test_spline_passes_through_every_via(k):
    vias = [make_transform([0.3 - 0.02 * i, 0.05 * (i + 1), 0.42 - 0.03 * i],
                           euler_zyx_to_matrix(0.1 * i, 1.3, 0.0)) for i in range(k)]
    poses = paths.spline_curve(T0, np.array(vias).reshape(k, 4, 4), T1, max_step=0.002).poses
    assert np.array_equal(poses[0], T0) and np.array_equal(poses[-1], T1)
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    assert steps.max() <= 0.002 * 1.01 and steps.min() >= 0.002 * 0.8    # even in arc length
    for V in vias:
        d = np.linalg.norm(poses[:, :3, 3] - V[:3, 3], axis=1)
        j = np.argmin(d)
        assert d[j] <= 0.002
        assert rotation_angle_between(poses[j, :3, :3], V[:3, :3]) < 0.05
    assert_valid_poses(poses)


def test_arc_through_via_point():
    via = np.array([0.33, 0.12, 0.45])
    poses = paths.arc_curve(T0, via, T1, n=401).poses
    center, r, e1, e2, ang_b, ang_c = paths.circle_through(T0[:3, 3], via, T1[:3, 3])
    d = np.linalg.norm(poses[:, :3, 3] - center, axis=1)
    assert np.allclose(d, r)
    normal = np.cross(e1, e2)
    assert np.allclose((poses[:, :3, 3] - center) @ normal, 0.0, atol=1e-12)
    assert np.linalg.norm(poses[:, :3, 3] - via, axis=1).min() <= r * ang_c / 400
    assert np.array_equal(poses[0], T0) and np.array_equal(poses[-1], T1)
    assert 0 < ang_b < ang_c < 2 * np.pi
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    assert np.allclose(steps, steps[0])                                  # even in angle


def test_arc_through_via_pose_reaches_its_orientation():
    T_via = make_transform([0.33, 0.12, 0.45], euler_zyx_to_matrix(0.8, 0.9, 0.1))
    poses = paths.arc_curve(T0, T_via, T1, n=401).poses
    j = np.argmin(np.linalg.norm(poses[:, :3, 3] - T_via[:3, 3], axis=1))
    assert rotation_angle_between(poses[j, :3, :3], T_via[:3, :3]) < 0.02


def test_circle_of_known_points():
    center, r, e1, e2, ang_b, ang_c = paths.circle_through([1, 0, 0], [0, 1, 0], [-1, 0, 0])
    assert np.allclose(center, 0.0) and r == pytest.approx(1.0)
    assert ang_b == pytest.approx(np.pi / 2) and ang_c == pytest.approx(np.pi)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
       st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6), st.integers(2, 40))
def test_random_linear_paths(pos, ang, n):
    Ta = make_transform(pos[:3], euler_zyx_to_matrix(*ang[:3]))
    Tb = make_transform(pos[3:], euler_zyx_to_matrix(*ang[3:]))
    assume(np.linalg.norm(Ta[:3, 3] - Tb[:3, 3]) >= 1e-9
           or rotation_angle_between(Ta[:3, :3], Tb[:3, :3]) >= 1e-9)   # two poses, not one
    poses = paths.linear_curve(Ta, Tb, n=n).poses
    assert np.array_equal(poses[0], Ta) and np.array_equal(poses[-1], Tb)
    assert_valid_poses(poses)
    turns = np.array([rotation_angle_between(a[:3, :3], b[:3, :3])
                      for a, b in zip(poses[:-1], poses[1:])])
    assert np.allclose(turns, turns[0], atol=1e-7)                      # constant-rate SLERP


BAD = np.array(T0)
BAD[0, 0] = 2.0


@pytest.mark.parametrize('call', [
    lambda: paths.linear_curve(T0, T0, n=10).poses,
    lambda: paths.linear_curve(T0, T1).poses,
    lambda: paths.linear_curve(T0, T1, n=10, max_step=0.01).poses,
    lambda: paths.linear_curve(T0, T1, n=1).poses,
    lambda: paths.linear_curve(T0, T1, max_step=0.0).poses,
    lambda: paths.linear_curve(T0, BAD, n=5).poses,
    lambda: paths.linear_curve(np.full((4, 4), np.nan), T1, n=5).poses,
    lambda: paths.parabolic_curve(T0, T1, float('inf'), n=5).poses,
    lambda: paths.spline_curve(T0, np.array([T0]), T1, n=5).poses,
    lambda: paths.spline_curve(T0, np.zeros((1, 3)), T1, n=5).poses,
    lambda: paths.arc_curve(T0, (T0[:3, 3] + T1[:3, 3]) / 2, T1, n=5).poses,
    lambda: paths.arc_curve(T0, T1[:3, 3], T1, n=5).poses,
])
def test_bad_input_raises(call):
    with pytest.raises(InvalidInputError):
        call()
