"""Closed-form IK: every branch, verified by FK, limits, singular poses, the miniBOT numbers."""

from hypothesis import given, settings
from hypothesis import strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import from_dh, minibot, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.ik_closed_form import (ik_closed_form, ik_closed_form_batch,
                                                      pose_errors_batch)
from mover6_control.kinematics.rotations import euler_zyx_to_matrix, pose_from_xyzabc
from mover6_control.kinematics.wrist import has_spherical_wrist, wrist_geometry
import numpy as np
import pytest
from scipy.optimize import brentq


def puma560():
    """Return a PUMA 560 (standard DH, Corke): spherical wrist, shoulder offset d3."""
    return from_dh([0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
                   [np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0],
                   [0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0], name='puma560',
                   lower=np.radians([-160, -225, -45, -110, -100, -266]),
                   upper=np.radians([160, 45, 225, 170, 100, 266]))


ARMS = {'mover6': mover6, 'mover6_hw': lambda: mover6('hardware'), 'minibot': minibot,
        'puma560': puma560}
# The miniBOT report question 1b: the pose (mm, 4-digit rotation) and the two solutions it found
# [deg].
MINIBOT_R = np.array([[0.7551, 0.4013, 0.5184], [0.6084, -0.7235, -0.3262],
                      [0.2441, 0.5617, -0.7905]])
MINIBOT_T_MM = np.array([399.1255, 171.01526, 416.0308])
MINIBOT_SOLUTIONS_DEG = np.array([[30.0, -15.998, 148.716, 145.037, 109.042, 156.916],
                                  [30.0, 60.0, 0.0, 134.998, 50.0, -157.501]])


def ur5():
    """Return a UR5 (DH from Universal Robots): 6R without a spherical wrist."""
    return from_dh([0, -0.425, -0.39225, 0, 0, 0], [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0],
                   [0.089159, 0, 0, 0.10915, 0.09465, 0.0823], name='ur5')


def _random_in_limits(arm, m, seed):
    return np.random.default_rng(seed).uniform(arm.lower, arm.upper, (m, arm.n_joints))


@pytest.mark.parametrize('name', sorted(ARMS))
def test_round_trip_on_random_poses(name):
    arm = ARMS[name]()
    Q = _random_in_limits(arm, 3000, 11)
    T = fk_batch(arm, Q)
    S, ok = ik_closed_form_batch(arm, T)
    assert ok.any(axis=1).all(), 'every pose made by FK of an in-limit q must be solved'
    dp, dr = pose_errors_batch(np.repeat(T, 8, axis=0), fk_batch(arm, S.reshape(-1, 6)))
    good = ok.reshape(-1)
    assert dp[good].max() < 1e-9 and dr[good].max() < 1e-9
    # The configuration that made the pose is one of the solutions (up to whole turns: with
    # the default q_ref = 0 the value nearest 0 is returned).
    gap = np.abs((S - Q[:, None] + np.pi) % (2 * np.pi) - np.pi).max(axis=2)
    assert np.where(ok, gap, np.inf).min(axis=1).max() < 1e-8
    # With the generating configuration as q_ref it comes back exactly.
    S, ok = ik_closed_form_batch(arm, T, q_ref=Q)
    assert np.where(ok, np.abs(S - Q[:, None]).max(axis=2), np.inf).min(axis=1).max() < 1e-8
    inside = (S >= arm.lower - 1e-9) & (S <= arm.upper + 1e-9)
    assert inside.all(axis=2)[ok].all()


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(ARMS)), st.integers(0, 2 ** 31))
def test_single_pose_solutions_are_unique_verified_and_sorted(name, seed):
    arm = ARMS[name]()
    q = _random_in_limits(arm, 1, seed)[0]
    T = fk(arm, q)
    sols = ik_closed_form(arm, T, q_ref=q)
    assert 1 <= len(sols) <= 8
    np.testing.assert_allclose(sols[0], q, atol=1e-8)          # nearest to q_ref first
    for s in sols:
        np.testing.assert_allclose(fk(arm, s), T, atol=1e-9)
        assert arm.within_limits(s)
    gaps = [np.abs(a - b).max() for i, a in enumerate(sols) for b in sols[i + 1:]]
    assert not gaps or min(gaps) > 1e-9
    everything = ik_closed_form(arm, T, within_limits=False)
    assert len(everything) >= len(sols)


def test_minibot_report_question_1b_all_eight_solutions():
    arm = minibot()
    u, _, vt = np.linalg.svd(MINIBOT_R)   # the miniBOT report's rotation is rounded to 4 digits
    T = np.eye(4)
    T[:3, :3] = u @ vt
    T[:3, 3] = MINIBOT_T_MM / 1000.0
    sols = ik_closed_form(arm, T)
    assert len(sols) == 8          # the miniBOT report found 2; the q1 + 180 deg family exists too
    for expected in MINIBOT_SOLUTIONS_DEG:
        nearest = np.abs(np.degrees(sols) - expected).max(axis=1).min()
        assert nearest < 0.01
    for s in sols:
        np.testing.assert_allclose(fk(arm, s), T, atol=1e-9)
    assert np.sum(np.isclose(np.degrees(sols[:, 0]), -150.0, atol=0.01)) == 4


def test_mover6_report_goal_absolute_vs_relative_reading():
    arm = mover6()
    T_abs = pose_from_xyzabc(0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)
    T_rel = T_abs.copy()
    T_rel[:3, :3] = fk(arm, np.zeros(6))[:3, :3] @ euler_zyx_to_matrix(0.0, 1.5708, 0.0)
    # Absolute (this project's convention): 8 solutions, none inside [-1.571, 1.571].
    assert len(ik_closed_form(arm, T_abs)) == 0
    outside = ik_closed_form(arm, T_abs, within_limits=False)
    assert len(outside) == 8
    assert min(len(arm.limit_violations(q)) for q in outside) == 1   # best: joint 3 only
    # Relative (the Mover6 report's MATLAB): exactly reachable inside its limits.
    sols = ik_closed_form(arm, T_rel)
    assert len(sols) == 1
    np.testing.assert_allclose(fk(arm, sols[0]), T_rel, atol=1e-12)
    np.testing.assert_allclose(sols[0][[0, 3, 5]], [-np.pi / 4, 0.0, np.pi / 4], atol=1e-4)


def test_wrist_singularity_takes_q4_from_the_reference():
    arm = mover6()
    T_home = fk(arm, np.zeros(6))
    np.testing.assert_allclose(ik_closed_form(arm, T_home)[0], np.zeros(6), atol=1e-12)
    ref = np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0])
    sol = ik_closed_form(arm, T_home, q_ref=ref)[0]
    np.testing.assert_allclose(sol, [0.0, 0.0, 0.0, 0.3, 0.0, -0.3], atol=1e-12)


def test_shoulder_singularity_takes_q1_from_the_reference():
    arm = mover6().with_limits(lower=np.full(6, -np.pi), upper=np.full(6, np.pi))
    geo = wrist_geometry(arm)

    def wrist_x(q3):
        T = fk(arm, [0.0, 0.2, q3, 0.0, 0.0, 0.0])
        return (T[:3, :3] @ geo.wrist_in_tip + T[:3, 3])[0]

    # Put the wrist centre on axis 1 (vertical through the base).
    q3 = brentq(wrist_x, -3.0, 0.0, xtol=1e-15)
    for q1_ref in (0.7, -0.3):
        q = np.array([q1_ref, 0.2, q3, 0.1, 0.5, -0.2])
        T = fk(arm, q)
        sols = ik_closed_form(arm, T, q_ref=q)
        np.testing.assert_allclose(sols[0], q, atol=1e-7)
        for s in sols:
            np.testing.assert_allclose(fk(arm, s), T, atol=1e-9)
            assert s[0] == pytest.approx(q1_ref) or abs(abs(s[0] - q1_ref) - np.pi) < 1e-9


def test_unreachable_pose_has_no_solution():
    for name in ARMS:
        sols = ik_closed_form(ARMS[name](), pose_from_xyzabc(2.0, 0.0, 0.3, 0.0, 0.0, 0.0))
        assert sols.shape == (0, 6)


def test_batch_agrees_with_single_pose():
    arm = minibot()
    Q = _random_in_limits(arm, 20, 5)
    S, ok = ik_closed_form_batch(arm, fk_batch(arm, Q), chunk=7)
    for k in range(20):
        single = ik_closed_form(arm, fk(arm, Q[k]))
        assert len(single) == len(np.unique(np.round(S[k][ok[k]], 9), axis=0))


def test_arms_without_a_spherical_wrist_are_refused():
    arm = ur5()
    assert not has_spherical_wrist(arm)
    with pytest.raises(InvalidInputError, match='spherical wrist'):
        ik_closed_form(arm, fk(arm, np.zeros(6)))
    assert has_spherical_wrist(mover6()) and has_spherical_wrist(minibot())
    three = from_dh([0.0, 0.3, 0.2], [np.pi / 2, 0.0, 0.0], [0.1, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match='6-joint'):
        ik_closed_form(three, np.eye(4))


@pytest.mark.parametrize('T, match', [
    (np.full((4, 4), np.nan), 'non-finite'),
    (np.diag([1.0, 1.0, 2.0, 1.0]), 'orthonormal'),
    (np.diag([1.0, 1.0, -1.0, 1.0]), 'reflection'),
    (np.eye(3), 'shape'),
])
def test_bad_poses_raise(T, match):
    with pytest.raises(InvalidInputError, match=match):
        ik_closed_form(mover6(), T)


def test_bad_batch_input_raises():
    with pytest.raises(InvalidInputError, match='non-finite'):
        ik_closed_form_batch(mover6(), np.full((2, 4, 4), np.inf))
    with pytest.raises(InvalidInputError, match='q_ref'):
        ik_closed_form_batch(mover6(), np.tile(np.eye(4), (2, 1, 1)), q_ref=np.zeros(5))
