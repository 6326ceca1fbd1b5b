"""
FK, Jacobian, rates and statics against the source documents' numbers.

FK against the Mover6 report's analytic H matrices and the miniBOT report's question 1a, joint
rates against the miniBOT report and statics against the Jacobians and trajectories report.
"""

from hypothesis import given, settings
from hypothesis import strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, from_dh, minibot, mover6
from mover6_control.kinematics.forward import (condition_number, fk, fk_and_jacobian, fk_batch,
                                               fk_frames, fk_frames_batch, jacobian,
                                               jacobian_batch, joint_rates, joint_torques,
                                               manipulability)
from mover6_control.kinematics.rotations import matrix_to_euler_zyx
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

Q6 = st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6).map(np.array)
# The Mover6 report eq. 23-29 link lengths l1..l6 [m] (from its verification script).
L = (0.130, 0.0625, 0.190, -0.06, 0.290, 0.055)
# The URDF writes pi/2 as 1.57079632679 (error 5e-12 rad), the miniBOT report's H_3^2 uses pi/2
# exactly.
URDF_PI_TOL = 1e-11
# The miniBOT report question 1b: the two solutions it found [deg] and their joint rates for the
# twist.
MINIBOT_SOLUTIONS = [([30.0, -15.998, 148.716, 145.037, 109.042, 156.916],
                      [-0.815, -1.407, 1.779, 2.056, -1.299, 0.792]),
                     ([30.0, 60.0, 0.0, 134.998, 50.0, -157.501],
                      [-0.815, 0.425, -1.779, -0.46, -3.518, 1.352])]
MINIBOT_TWIST = np.array([0.100, -0.200, -0.300, 2.0, -1.0, 0.5])  # mm/s -> m/s; rad/s


def _h(R, p):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def mover6_report_h06(q):
    """Return H_6^0 of the Mover6 report eq. 23-29, term by term."""
    l1, l2, l3, l4, l5, l6 = L
    z3 = np.zeros(3)
    H01 = _h(np.eye(3), [0, 0, l1]) @ _h(_rz(-q[0]), z3)
    H12 = _h(np.eye(3), [0, 0, l2]) @ _h(_ry(q[1]), z3)
    H23 = _h(_ry(np.pi / 2), [0, 0, l3]) @ _h(_ry(q[2]), z3)
    H34 = _h(np.eye(3), [l4, 0, 0]) @ _h(_rz(q[3]), z3)
    H45 = _h(np.eye(3), [0, 0, l5]) @ _h(_ry(q[4]), z3)
    H56 = _h(np.eye(3), [0, 0, l6]) @ _h(_rz(q[5]), z3)
    return H01 @ H12 @ H23 @ H34 @ H45 @ H56


def test_fk_matches_mover6_report_analytic_example():
    q = np.array([0.6, -np.pi / 6, np.pi / 8, -np.pi / 6, -np.pi / 4, np.pi / 3])
    np.testing.assert_allclose(fk(mover6(), q), mover6_report_h06(q), atol=URDF_PI_TOL)


@settings(max_examples=60, deadline=None)
@given(Q6)
def test_fk_matches_mover6_report_analytic_everywhere(q):
    np.testing.assert_allclose(fk(mover6(), q), mover6_report_h06(q), atol=URDF_PI_TOL)


def test_minibot_fk_matches_minibot_report_question_1a():
    # the miniBOT report: FK of [0, 90, 0, 0, -90, 0] deg is (277.5, 0, 564) mm, ZYX Euler (180, 0,
    # 0).
    T = fk(minibot(), np.radians([0.0, 90.0, 0.0, 0.0, -90.0, 0.0]))
    np.testing.assert_allclose(T[:3, 3], [0.2775, 0.0, 0.564], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    a, b, c = matrix_to_euler_zyx(T[:3, :3])
    assert abs(abs(a) + abs(c) - np.pi) < 1e-9 and abs(b) < 1e-9


def test_batched_fk_equals_single_fk():
    rng = np.random.default_rng(3)
    for arm in (mover6(), minibot()):
        Q = rng.uniform(-np.pi, np.pi, (5000, 6))   # more than one internal block
        T = fk_batch(arm, Q)
        for k in (0, 1234, 4095, 4096, 4999):
            np.testing.assert_allclose(T[k], mover6_report_h06(Q[k]) if arm.name == 'mover6'
                                       else fk(arm, Q[k]), atol=URDF_PI_TOL)
        frames = fk_frames(arm, Q[7])
        np.testing.assert_allclose(frames[-1], T[7], atol=1e-12)
        np.testing.assert_allclose(frames[0][:3, 3], fk_frames(arm, np.zeros(6))[0][:3, 3])


@pytest.mark.parametrize('name', ['mover6', 'minibot', 'tilted'])
def test_single_configuration_path_equals_the_batched_one(name):
    # fk, fk_frames, jacobian and fk_and_jacobian of one configuration skip the batched set-up.
    rng = np.random.default_rng(11)
    arm = {'mover6': mover6, 'minibot': minibot}.get(name, lambda: _tilted_arm(rng))()
    Q = rng.uniform(-np.pi, np.pi, (200, arm.n_joints))
    frames, J = fk_frames_batch(arm, Q), jacobian_batch(arm, Q)
    for k, q in enumerate(Q):
        np.testing.assert_allclose(fk_frames(arm, q), frames[k], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(fk(arm, q), frames[k, -1], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(jacobian(arm, q), J[k], rtol=0.0, atol=1e-12)
        T, J_k = fk_and_jacobian(arm, q)
        np.testing.assert_allclose(T, frames[k, -1], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(J_k, J[k], rtol=0.0, atol=1e-12)


def _tilted_arm(rng, n=5):
    """Return an arm with random joint origins and axes off the coordinate axes (but one)."""
    origins = np.tile(np.eye(4), (n, 1, 1))
    origins[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
    origins[:, :3, 3] = rng.uniform(-0.3, 0.3, (n, 3))
    axes = rng.normal(size=(n, 3))
    axes[0] = [0.0, 0.0, -1.0]                        # mix in an aligned one
    tool = np.eye(4)
    tool[:3, 3] = [0.01, 0.02, 0.1]
    return ArmModel(name='tilted', joint_names=tuple(f'j{i}' for i in range(n)),
                    origins=origins, axes=axes, tool=tool, lower=-np.full(n, 3.0),
                    upper=np.full(n, 3.0), velocity_limits=np.ones(n))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31))
def test_fk_of_an_arm_with_tilted_axes_equals_the_product_of_its_joints(seed):
    # Axes off the coordinate axes take the general (Rodrigues) path of the batched FK.
    rng = np.random.default_rng(seed)
    n = 5
    origins = np.tile(np.eye(4), (n, 1, 1))
    origins[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    origins[:, :3, 3] = rng.uniform(-0.3, 0.3, (n, 3))
    axes = rng.normal(size=(n, 3))
    axes[0] = [0.0, 0.0, -1.0]                        # mix in an aligned one
    tool = np.eye(4)
    tool[:3, 3] = [0.01, 0.02, 0.1]
    arm = ArmModel(name='tilted', joint_names=tuple(f'j{i}' for i in range(n)),
                   origins=origins, axes=axes, tool=tool, lower=-np.full(n, 3.0),
                   upper=np.full(n, 3.0), velocity_limits=np.ones(n))
    q = rng.uniform(-3.0, 3.0, n)
    T = np.eye(4)
    for i in range(n):
        R = np.eye(4)
        R[:3, :3] = Rotation.from_rotvec(arm.axes[i] * q[i]).as_matrix()
        T = T @ origins[i] @ R
    np.testing.assert_allclose(fk(arm, q), T @ tool, atol=1e-12)
    np.testing.assert_allclose(fk_batch(arm, np.array([q, q]))[1], T @ tool, atol=1e-12)


def _numeric_jacobian(arm, q, h=1e-6):
    J = np.zeros((6, 6))
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        Tp, Tm = fk(arm, q + dq), fk(arm, q - dq)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, i] = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
    return J


@settings(max_examples=30, deadline=None)
@given(Q6, st.sampled_from(['mover6', 'minibot']))
def test_jacobian_is_the_derivative_of_fk(q, name):
    arm = mover6() if name == 'mover6' else minibot()
    np.testing.assert_allclose(jacobian(arm, q), _numeric_jacobian(arm, q), atol=1e-7)
    np.testing.assert_allclose(jacobian_batch(arm, q[None])[0], jacobian(arm, q))


@pytest.mark.parametrize('solution_deg, rates', MINIBOT_SOLUTIONS)
def test_joint_rates_match_minibot_report_question_2(solution_deg, rates):
    arm = minibot()
    q = np.radians(solution_deg)
    qd = joint_rates(arm, q, MINIBOT_TWIST, damping=0.0)
    np.testing.assert_allclose(qd, rates, atol=2e-3)
    np.testing.assert_allclose(jacobian(arm, q) @ qd, MINIBOT_TWIST, atol=1e-9)
    # The default small damping changes nothing measurable away from singularities.
    np.testing.assert_allclose(joint_rates(arm, q, MINIBOT_TWIST), qd, atol=1e-3)


def test_damping_bounds_the_rates_at_a_singularity():
    arm = mover6()
    q = np.zeros(6)                       # home: axes 4 and 6 aligned
    assert manipulability(arm, q) < 1e-12
    assert condition_number(arm, q) > 1e12
    twist = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])  # spin about the aligned axes: fine
    qd = joint_rates(arm, q, np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0]), damping=0.05)
    assert np.all(np.isfinite(qd)) and np.abs(qd).max() < 50.0
    np.testing.assert_allclose(jacobian(arm, q) @ joint_rates(arm, q, twist, damping=0.0),
                               twist, atol=1e-9)
    q_good = np.array([0.3, 0.4, 0.5, 0.2, 0.8, 0.1])
    assert manipulability(arm, q_good) > 1e-3
    assert 1.0 < condition_number(arm, q_good) < 100.0


def test_statics_match_jacobians_report():
    # the Jacobians and trajectories report's 3R wrist: alpha1 = alpha2 = 120 deg; at theta1 = 0,
    # theta2 = 90 deg its
    # Jacobian in frame 2 (Q1^T [J]_1) is given, and J^T n = tau = (20, 20, -10) for
    # n = (0, 20 sqrt 3, 20) N m.
    arm = from_dh([0.0, 0.0, 0.5], [2 * np.pi / 3, 2 * np.pi / 3, 0.0], [0.0, 0.0, 0.0])
    q = np.array([0.0, np.pi / 2, 0.4])
    c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
    Q1 = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    J2 = np.array([[0.0, 0.0, np.sqrt(3) / 2], [np.sqrt(3) / 2, 0.0, 0.0], [-0.5, 1.0, -0.5]])
    np.testing.assert_allclose(Q1.T @ jacobian(arm, q)[3:], J2, atol=1e-12)
    n = Q1 @ np.array([0.0, 20.0 * np.sqrt(3), 20.0])
    tau = joint_torques(arm, q, np.concatenate([np.zeros(3), n]))
    np.testing.assert_allclose(tau, [20.0, 20.0, -10.0], atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(Q6, st.lists(st.floats(-10, 10), min_size=6, max_size=6),
       st.lists(st.floats(-2, 2), min_size=6, max_size=6))
def test_statics_and_rates_are_power_dual(q, wrench, qd):
    arm = minibot()
    twist = jacobian(arm, q) @ np.array(qd)
    assert np.dot(joint_torques(arm, q, wrench), qd) == pytest.approx(
        np.dot(wrench, twist), abs=1e-9)


@pytest.mark.parametrize('call, match', [
    (lambda a: fk(a, [0.0] * 5), 'shape'),
    (lambda a: fk(a, [0.0, 0.0, float('nan'), 0.0, 0.0, 0.0]), 'non-finite'),
    (lambda a: fk_batch(a, np.zeros((3, 5))), 'shape'),
    (lambda a: jacobian(a, [float('inf')] * 6), 'non-finite'),
    (lambda a: joint_rates(a, np.zeros(6), [0.0] * 5), 'twist'),
    (lambda a: joint_rates(a, np.zeros(6), [0.0] * 6, damping=-1.0), 'damping'),
    (lambda a: joint_torques(a, np.zeros(6), [0.0, 0.0, float('nan'), 0, 0, 0]), 'wrench'),
])
def test_bad_input_raises(call, match):
    with pytest.raises(InvalidInputError, match=match):
        call(mover6())
