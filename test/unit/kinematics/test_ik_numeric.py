"""Numeric IK: converges on any arm, keeps the limits, finds the closest pose when unreachable."""

from hypothesis import given, settings
from hypothesis import strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import from_dh, minibot, mover6
from mover6_control.kinematics.forward import fk, fk_batch, jacobian
from mover6_control.kinematics.ik_numeric import (closest_within_limits, ik_numeric,
                                                  pose_residual_batch, screw_chain)
from mover6_control.kinematics.rotations import pose_error, pose_from_xyzabc, rotation_log_batch
import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation


def ur5():
    """Return a UR5 (DH from Universal Robots): no spherical wrist, no closed form here."""
    return from_dh([0, -0.425, -0.39225, 0, 0, 0], [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0],
                   [0.089159, 0, 0, 0.10915, 0.09465, 0.0823], name='ur5')


@pytest.mark.parametrize('make', [mover6, minibot, ur5])
def test_converges_from_zero_on_random_poses(make):
    arm = make()
    Q = np.random.default_rng(21).uniform(arm.lower, arm.upper, (25, 6))
    for k, T in enumerate(fk_batch(arm, Q)):
        res = ik_numeric(arm, T, np.zeros(6), rng=k)
        assert res.success, f'pose {k} failed: {res}'
        pos, rot = pose_error(fk(arm, res.q), T)
        assert pos < 1e-6 and rot < 1e-6
        assert res.position_error == pytest.approx(pos, abs=1e-9)
        assert arm.within_limits(res.q)
        assert res.iterations >= 1


def test_a_nearby_seed_converges_to_the_nearby_solution():
    arm = ur5()
    q = np.array([0.4, -1.2, 1.0, -0.5, 0.8, 0.3])
    res = ik_numeric(arm, fk(arm, q), q + 0.05, n_seeds=1)
    assert res.success and res.restarts == 0
    np.testing.assert_allclose(res.q, q, atol=1e-6)


def test_rotation_log_matches_scipy_including_zero_and_pi():
    rv = Rotation.random(400, random_state=2).as_rotvec()
    rv[:20] *= (np.pi - 1e-7) / np.linalg.norm(rv[:20], axis=1, keepdims=True)
    rv[20:40] *= 3.05 / np.linalg.norm(rv[20:40], axis=1, keepdims=True)
    rv[40:60] *= 1e-9
    R = Rotation.from_rotvec(rv).as_matrix()
    np.testing.assert_allclose(rotation_log_batch(R), rv, atol=1e-9)
    np.testing.assert_allclose(rotation_log_batch(np.eye(3)[None]), np.zeros((1, 3)))


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6),
       st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6))
def test_residual_is_the_pose_error_and_its_jacobian(q, q_goal):
    for arm in (mover6(), ur5()):
        T_goal = fk(arm, q_goal)
        e, J = pose_residual_batch(screw_chain(arm), np.array([q, q_goal]), T_goal)
        np.testing.assert_allclose(J[0], jacobian(arm, q), atol=1e-12)
        np.testing.assert_allclose(e[1], np.zeros(6), atol=1e-12)
        T = fk(arm, q)
        np.testing.assert_allclose(e[0, :3], T_goal[:3, 3] - T[:3, 3], atol=1e-12)
        rv = Rotation.from_matrix(T_goal[:3, :3] @ T[:3, :3].T).as_rotvec()
        if np.linalg.norm(rv) < np.pi - 1e-6:      # the sign is arbitrary at pi
            np.testing.assert_allclose(e[0, 3:], rv, atol=1e-9)


def test_unreachable_pose_returns_the_best_in_limit_attempt():
    arm = mover6()
    T = pose_from_xyzabc(1.0, 0.0, 0.3, 0.0, 0.0, 0.0)
    res = ik_numeric(arm, T, np.zeros(6), max_iterations=60)
    assert not res.success
    assert arm.within_limits(res.q)
    pos, rot = pose_error(fk(arm, res.q), T)
    assert res.position_error == pytest.approx(pos, abs=1e-9)
    assert 0.4 < pos < 1.0          # the arm reaches about 0.6 m of the 1.04 m asked


def _weighted_residual(arm, T, w):
    def residual(q):
        Tq = fk(arm, q)
        rot = Rotation.from_matrix(T[:3, :3] @ Tq[:3, :3].T).as_rotvec()
        return np.sqrt(w) * np.concatenate([T[:3, 3] - Tq[:3, 3], rot])
    return residual


def test_closest_pose_is_no_worse_than_scipy_on_the_same_cost():
    # the Mover6 report's goal read absolutely is outside its +-90 deg limits (joint 3).
    arm = mover6()
    T = pose_from_xyzabc(0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)
    w = np.array([1.0, 1.0, 1.0, 0.01, 0.01, 0.01])
    best = closest_within_limits(arm, T, np.zeros((1, 6)), weights=w)
    assert not best.success and arm.within_limits(best.q)
    fun = _weighted_residual(arm, T, w)
    assert best.cost == pytest.approx(float(fun(best.q) @ fun(best.q)), rel=1e-9)
    rng = np.random.default_rng(0)
    scipy_costs = []
    for _ in range(6):
        sol = least_squares(fun, rng.uniform(arm.lower, arm.upper), bounds=(arm.lower, arm.upper))
        scipy_costs.append(2.0 * sol.cost)
    assert best.cost <= min(scipy_costs) * (1.0 + 1e-6)


@pytest.mark.parametrize('kwargs, match', [
    ({'T': np.full((4, 4), np.nan)}, 'non-finite'),
    ({'T': np.diag([1.0, 2.0, 1.0, 1.0])}, 'orthonormal'),
    ({'q0': np.zeros(5)}, 'q0'),
    ({'weights': [1, 1, 1, 0, 1, 1]}, 'weights'),
    ({'position_tol': -1.0}, 'position_tol'),
    ({'n_seeds': 0}, 'n_seeds'),
])
def test_bad_input_raises(kwargs, match):
    args = {'T': np.eye(4), 'q0': np.zeros(6)}
    args.update(kwargs)
    T, q0 = args.pop('T'), args.pop('q0')
    with pytest.raises(InvalidInputError, match=match):
        ik_numeric(mover6(), T, q0, **args)
