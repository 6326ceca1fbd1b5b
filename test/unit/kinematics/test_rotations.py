"""The rotation conversions in numpy against scipy's ``Rotation`` and ``Slerp`` (the reference)."""

from mover6_control.kinematics import rotations
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

# Half turns about each axis and the identity: where the largest of the trace and the diagonal
# changes, and where a formula that divides by w would fail.
EDGES = np.array([np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
                  np.diag([-1.0, -1.0, 1.0]), np.eye(3),
                  Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix(),
                  Rotation.from_rotvec(np.pi * np.array([1.0, 1.0, 0.0]) / np.sqrt(2)).as_matrix(),
                  Rotation.from_rotvec([0.0, 0.0, 1e-12]).as_matrix()])


def matrices():
    return np.concatenate([Rotation.random(2000, random_state=7).as_matrix(), EDGES])


def with_w_positive(q):
    return np.where(q[..., 3:] < 0.0, -q, q)


def test_matrix_to_quaternion_matches_scipy_one_by_one_and_in_a_batch():
    R = matrices()
    reference = with_w_positive(Rotation.from_matrix(R).as_quat())
    batch = rotations.matrices_to_quaternions(R)
    single = np.array([rotations.matrix_to_quaternion(m) for m in R])
    assert np.abs(batch - reference).max() < 1e-12
    assert np.abs(single - batch).max() < 1e-15
    assert (batch[:, 3] >= 0.0).all()


def test_quaternion_to_matrix_matches_scipy_and_inverts_matrix_to_quaternion():
    R = matrices()
    q = Rotation.from_matrix(R).as_quat()
    assert np.abs(rotations.unit_quaternion_to_matrix(q) - R).max() < 1e-12
    q_ours = rotations.matrices_to_quaternions(R)
    back = np.array([rotations.quaternion_to_matrix(v) for v in q_ours])
    assert np.abs(back - R).max() < 1e-12


def test_euler_zyx_matches_scipy_intrinsic_zyx():
    rng = np.random.default_rng(3)
    for a, b, c in rng.uniform(-4.0, 4.0, (500, 3)):
        expected = Rotation.from_euler('ZYX', [a, b, c]).as_matrix()
        assert np.abs(rotations.euler_zyx_to_matrix(a, b, c) - expected).max() < 1e-12


def test_rotation_angle_matches_scipy_and_keeps_its_digits_near_zero_and_pi():
    R = matrices()
    for R_a, R_b in zip(R[::2], R[1::2]):
        expected = Rotation.from_matrix(R_a.T @ R_b).magnitude()
        assert abs(rotations.rotation_angle_between(R_a, R_b) - expected) < 1e-12
    for angle in (1e-12, 1e-9, 1e-6, np.pi - 1e-9, np.pi):
        R_b = Rotation.from_rotvec([0.0, angle, 0.0]).as_matrix()
        assert rotations.rotation_angle_between(np.eye(3), R_b) == pytest.approx(angle, rel=1e-6)


@pytest.mark.parametrize('n_keys', [2, 3, 7])
def test_slerp_matches_scipy_between_and_beyond_its_keys(n_keys):
    rng = np.random.default_rng(n_keys)
    keys = np.cumsum(rng.uniform(0.1, 1.0, n_keys))
    R_keys = Rotation.random(n_keys, random_state=n_keys).as_matrix()
    params = np.linspace(keys[0] - 0.5, keys[-1] + 0.5, 997)
    expected = Slerp(keys, Rotation.from_matrix(R_keys))(np.clip(params, keys[0], keys[-1]))
    assert np.abs(rotations.slerp(keys, R_keys, params) - expected.as_matrix()).max() < 1e-12


@pytest.mark.parametrize('angle', [0.0, 1e-12, 1e-6, 3.1, np.pi - 1e-6])
def test_slerp_turns_the_shorter_way_at_a_constant_rate_about_one_axis(angle):
    R_goal = Rotation.from_rotvec([0.0, 0.0, angle]).as_matrix()
    u = np.linspace(0.0, 1.0, 101)
    R = rotations.slerp([0.0, 1.0], [np.eye(3), R_goal], u)
    expected = Rotation.from_rotvec(np.outer(u, [0.0, 0.0, angle])).as_matrix()
    assert np.abs(R - expected).max() < 1e-12
