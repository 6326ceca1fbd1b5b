"""The frozen input values: each made and checked once, each refusal with its code."""

import math

from mover6_control.errors import error_code, INPUT_CODES, InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.values import JogRequest, JointDemand, poses_of, ToolPose
import numpy as np
import pytest

ARM = mover6()
T = fk(ARM, np.array([0.3, 0.2, 0.1, 0.2, 0.3, 0.1]))
NAMES = ['joint1', 'joint2', 'joint3', 'joint4', 'joint5', 'joint6']


def code_of(make):
    """Return the code ``make()`` is refused with (it must be refused)."""
    with pytest.raises(InvalidInputError) as refused:
        make()
    assert error_code(refused.value) in INPUT_CODES
    return error_code(refused.value)


# --- ToolPose --------------------------------------------------------------------------------

def test_a_pose_keeps_a_read_only_copy_and_reads_as_its_matrix():
    raw = T.copy()
    pose = ToolPose.from_matrix(raw)
    raw[0, 3] = 9.0                                     # the caller's array is not the pose's
    np.testing.assert_array_equal(pose.matrix, T)
    np.testing.assert_array_equal(np.asarray(pose), T)
    np.testing.assert_array_equal(pose[:3, 3], T[:3, 3])
    np.testing.assert_array_equal(pose.position, T[:3, 3])
    np.testing.assert_array_equal(pose.rotation, T[:3, :3])
    with pytest.raises(ValueError):
        pose.matrix[0, 3] = 1.0
    np.testing.assert_array_equal(ToolPose(T).matrix, T)


def test_of_passes_a_pose_through_and_checks_raw_input():
    pose = ToolPose.from_matrix(T)
    assert ToolPose.of(pose) is pose
    assert isinstance(ToolPose.of(T), ToolPose)
    assert code_of(lambda: ToolPose.of(np.eye(3))) == 'bad_shape'


def test_a_pose_from_a_quaternion_is_the_matrix_of_that_rotation():
    s = math.sqrt(0.5)
    pose = ToolPose.from_position_quaternion([0.1, 0.2, 0.3], [0.0, 0.0, s, s])
    np.testing.assert_allclose(pose.rotation, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_array_equal(pose.position, [0.1, 0.2, 0.3])


def reflected():
    bad = T.copy()
    bad[:3, 0] *= -1.0
    return bad


def sheared():
    bad = T.copy()
    bad[0, 1] += 0.01
    return bad


def bad_last_row():
    bad = T.copy()
    bad[3, 0] = 0.1
    return bad


def with_nan():
    bad = T.copy()
    bad[1, 3] = math.nan
    return bad


@pytest.mark.parametrize('raw, code', [
    ('a pose', 'bad_shape'),
    (np.eye(3), 'bad_shape'),
    ([[1, 2], [3]], 'bad_shape'),
    (with_nan(), 'non_finite'),
    (np.full((4, 4), math.inf), 'non_finite'),
    (sheared(), 'not_a_transform'),
    (reflected(), 'not_a_transform'),
    (bad_last_row(), 'not_a_transform'),
])
def test_a_bad_matrix_is_refused_with_its_code(raw, code):
    assert code_of(lambda: ToolPose.from_matrix(raw)) == code
    assert code_of(lambda: ToolPose(raw)) == code


@pytest.mark.parametrize('position, quaternion, code', [
    ([0.1, 0.2, math.nan], [0, 0, 0, 1], 'non_finite'),
    ([0.1, 0.2], [0, 0, 0, 1], 'bad_shape'),
    ([0.1, 0.2, 0.3], [0, 0, 0, math.inf], 'non_finite'),
    ([0.1, 0.2, 0.3], [0, 0, 0, 0], 'bad_quaternion'),
    ([0.1, 0.2, 0.3], [0, 0, 0, 2], 'bad_quaternion'),
])
def test_a_bad_position_or_quaternion_is_refused_with_its_code(position, quaternion, code):
    assert code_of(lambda: ToolPose.from_position_quaternion(position, quaternion)) == code


def test_poses_of_checks_raw_matrices_once_each_and_passes_poses_through():
    pose = ToolPose.from_matrix(T)
    assert poses_of([pose, pose])[1] is pose
    assert [p.matrix.tolist() for p in poses_of(np.stack([T, T]))] == [T.tolist()] * 2
    assert poses_of(np.zeros((0, 4, 4))) == []
    assert code_of(lambda: poses_of(np.stack([T, reflected()]))) == 'not_a_transform'
    assert code_of(lambda: poses_of('abc')) == 'bad_shape'


# --- JogRequest ------------------------------------------------------------------------------

def test_a_jog_keeps_its_names_and_velocities_as_tuples():
    jog = JogRequest.from_fields(['joint2', 'joint1'], np.array([0.1, -0.2]))
    assert jog.names == ('joint2', 'joint1') and jog.velocities == (0.1, -0.2)
    assert jog.indices(NAMES) == (1, 0)
    with pytest.raises(AttributeError):
        jog.names = ('joint3',)


@pytest.mark.parametrize('names, velocities, displacements, code', [
    (['joint1'], [0.1], [0.1], 'displacements'),
    ([], [], [], 'empty'),
    (['joint1', 'joint2'], [0.1], [], 'length'),
    (['joint1'], [0.1, 0.2], [], 'length'),
    (['joint1', 'joint1'], [0.1, 0.1], [], 'names'),
    (['joint1'], [math.nan], [], 'non_finite'),
    (['joint1'], [-math.inf], [], 'non_finite'),
    (['joint1'], ['fast'], [], 'bad_shape'),
])
def test_a_bad_jog_is_refused_with_its_code(names, velocities, displacements, code):
    assert code_of(lambda: JogRequest.from_fields(names, velocities, displacements)) == code


def test_a_jog_naming_a_joint_the_arm_lacks_is_refused_by_its_consumer():
    jog = JogRequest(['joint1', 'wrist'], [0.1, 0.1])
    assert code_of(lambda: jog.indices(NAMES)) == 'unknown_joint'


# --- JointDemand -----------------------------------------------------------------------------

def test_a_demand_is_rows_of_joint_positions_read_only():
    demand = JointDemand.from_rows(list(range(12)), 6)
    assert demand.positions.shape == (2, 6) and demand.n_waypoints == 2
    with pytest.raises(ValueError):
        demand.positions[0, 0] = 1.0
    assert JointDemand(np.zeros((3, 6))).n_waypoints == 3


@pytest.mark.parametrize('values, code', [
    ([], 'empty'),
    ([0.0] * 7, 'bad_shape'),
    ([0.0] * 5 + [math.nan], 'non_finite'),
    (['a'] * 6, 'bad_shape'),
])
def test_a_bad_demand_is_refused_with_its_code(values, code):
    assert code_of(lambda: JointDemand.from_rows(values, 6)) == code


# --- the codes -------------------------------------------------------------------------------

def test_an_input_error_takes_only_a_code_of_the_table():
    assert InvalidInputError('x', 'length').code == 'length'
    assert InvalidInputError('x').code == 'invalid_input'
    with pytest.raises(KeyError):
        InvalidInputError('x', 'no such code')
