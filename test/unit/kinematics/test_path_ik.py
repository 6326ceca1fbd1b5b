"""Path IK: one continuous branch, and each failure reason with its details."""

from hypothesis import assume, given, settings
from hypothesis import strategies as st
from mover6_control.errors import InvalidInputError, REASONS, UnreachableError
from mover6_control.kinematics.arm import from_dh, minibot, mover6
from mover6_control.kinematics.forward import condition_number, fk, fk_batch
from mover6_control.kinematics.ik_closed_form import (ik_closed_form, nearest_alias,
                                                      solve_candidates)
from mover6_control.kinematics.path_ik import (branch_steps, holds_pose, PathSolution,
                                               single_turn, solve_path)
from mover6_control.kinematics.rotations import pose_error, pose_from_xyzabc
from mover6_control.kinematics.wrist import wrist_geometry
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

DETAIL_KEYS = {'waypoint', 'position_error', 'orientation_error', 'closest_q', 'closest_pose'}


def ur5():
    """Return a UR5 (DH from Universal Robots): no spherical wrist, solved numerically."""
    return from_dh([0, -0.425, -0.39225, 0, 0, 0], [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0],
                   [0.089159, 0, 0, 0.10915, 0.09465, 0.0823], name='ur5')


def line(T0, T1, n=30):
    """Return poses (n, 4, 4) on the straight line T0 -> T1 with T0's orientation."""
    P = np.tile(T0, (n, 1, 1))
    s = np.linspace(0.0, 1.0, n)[:, None]
    P[:, :3, 3] = (1.0 - s) * T0[:3, 3] + s * T1[:3, 3]
    return P


def _check_details(err, arm, T):
    assert err.reason in REASONS
    assert DETAIL_KEYS <= set(err.details)
    d = err.details
    assert arm.within_limits(d['closest_q'])
    np.testing.assert_allclose(d['closest_pose'], fk(arm, d['closest_q']), atol=1e-12)
    pos, rot = pose_error(d['closest_pose'], T)
    assert d['position_error'] == pytest.approx(pos, abs=1e-12)
    assert d['orientation_error'] == pytest.approx(rot, abs=1e-12)


def test_mover6_report_default_line_from_home():
    # the Mover6 report's default goal: 10 cm forward at the home orientation, from home (a wrist
    # singularity, which the path may leave).
    arm = mover6()
    T0 = fk(arm, np.zeros(6))
    T1 = T0.copy()
    T1[0, 3] = 0.445
    poses = line(T0, T1, 20)
    sol = solve_path(arm, poses, np.zeros(6), max_condition=1000.0)
    assert isinstance(sol, PathSolution) and sol.method == 'closed_form'
    assert sol.q.shape == (20, 6)
    np.testing.assert_allclose(fk_batch(arm, sol.q), poses, atol=1e-9)
    assert sol.max_joint_step <= 0.35 and sol.joint_step[0] == 0.0
    assert all(arm.within_limits(q) for q in sol.q)
    assert np.all(np.diff(sol.condition) < 0.0)      # leaving the singularity


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2 ** 31), st.sampled_from(['mover6', 'minibot']))
def test_path_stays_on_the_branch_of_q_start(seed, name):
    arm = mover6('hardware') if name == 'mover6' else minibot()
    rng = np.random.default_rng(seed)
    q_start = rng.uniform(arm.lower * 0.8, arm.upper * 0.8)
    q_end = np.clip(q_start + rng.uniform(-0.4, 0.4, 6), arm.lower, arm.upper)
    s = np.linspace(0.0, 1.0, 25)[:, None]
    joint_path = q_start + s * (q_end - q_start)
    conds = [condition_number(arm, q) for q in joint_path]
    assume(max(conds) < 300.0)                  # a branch is only defined off singularities
    sol = solve_path(arm, fk_batch(arm, joint_path), q_start)
    np.testing.assert_allclose(sol.q, joint_path, atol=1e-7)


def test_leaving_the_singular_home_turns_q4_against_q6_in_place():
    # From home (q5 = 0) towards this orientation the wrist must first turn q4 by ~0.41 rad:
    # a step larger than max_joint_step, allowed because the tool does not move.
    arm = mover6()
    T0 = fk(arm, np.zeros(6))
    T1 = fk(arm, np.array([0.2, 0.3, 0.2, 0.8, 0.5, -0.3]))
    n = 30
    s = np.linspace(0.0, 1.0, n)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([T0[:3, :3], T1[:3, :3]]))(
        s).as_matrix()
    poses[:, :3, 3] = (1.0 - s)[:, None] * T0[:3, 3] + s[:, None] * T1[:3, 3]
    sol = solve_path(arm, poses, np.zeros(6))
    np.testing.assert_allclose(fk_batch(arm, sol.q), poses, atol=1e-9)
    assert sol.self_motion[0] and not sol.self_motion[1:].any()
    assert sol.joint_step[0] > 0.35 >= sol.joint_step[~sol.self_motion].max()
    assert holds_pose(arm, np.zeros(6), sol.q[0], T0, 1e-9, 1e-9)
    assert not holds_pose(arm, sol.q[0], sol.q[1], T0, 1e-6, 1e-6)


def test_multi_turn_joint_crosses_180_degrees_without_a_jump():
    # PUMA 560 joint 6 turns +-266 deg: from 170 to 200 deg is continuous, not a 2 pi jump.
    arm = from_dh([0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0],
                  [np.pi / 2, 0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0],
                  [0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0], name='puma560',
                  lower=np.radians([-160, -225, -45, -110, -100, -266]),
                  upper=np.radians([160, 45, 225, 170, 100, 266]))
    q_start = np.array([0.3, -0.8, 0.5, 0.4, 0.7, np.radians(170.0)])
    s = np.linspace(0.0, 1.0, 20)[:, None]
    joint_path = q_start + s * np.array([0.1, 0.1, 0.0, 0.1, 0.0, np.radians(30.0)])
    sol = solve_path(arm, fk_batch(arm, joint_path), q_start)
    np.testing.assert_allclose(sol.q, joint_path, atol=1e-9)
    assert sol.q[-1, 5] > np.pi


def test_same_pose_on_another_branch_is_a_discontinuity():
    arm = minibot()
    q_a = np.array([0.3, 0.5, 0.2, 0.4, 0.6, 0.1])
    T = fk(arm, q_a)
    q_b = next(q for q in ik_closed_form(arm, T) if np.abs(q - q_a).max() > 1.0)
    # Starting from q_b, the path to T's pose continues on q_b's branch: fine.
    sol = solve_path(arm, np.array([T, T]), q_b)
    np.testing.assert_allclose(sol.q, [q_b, q_b], atol=1e-9)
    # Jumping from q_a's neighbourhood to a pose only reachable far away fails.
    far = fk(arm, q_a + np.array([1.2, 0.0, 0.0, 0.0, 0.0, 0.0]))
    with pytest.raises(UnreachableError) as info:
        solve_path(arm, np.array([T, far]), q_a)
    err = info.value
    assert err.reason == 'discontinuity' and err.details['waypoint'] == 1
    assert err.details['joint'] == 'joint1'
    assert err.details['joint_step'] == pytest.approx(1.2, abs=1e-9)
    np.testing.assert_allclose(err.details['closest_q'], q_a, atol=1e-9)
    _check_details(err, arm, far)


def test_goal_outside_the_limits_reports_joint_limits():
    arm = mover6()
    # the Mover6 report, absolute reading
    T_goal = pose_from_xyzabc(0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)
    with pytest.raises(UnreachableError) as info:
        solve_path(arm, np.array([fk(arm, np.zeros(6)), T_goal]), np.zeros(6),
                   max_joint_step=10.0)
    err = info.value
    assert err.reason == 'joint_limits' and err.details['waypoint'] == 1
    assert 'joint3' in str(err)
    _check_details(err, arm, T_goal)
    assert 0.0 < err.details['position_error'] < 0.02


def test_goal_out_of_reach():
    arm = mover6()
    T_goal = pose_from_xyzabc(0.9, 0.0, 0.3, 0.0, 0.0, 0.0)
    with pytest.raises(UnreachableError) as info:
        solve_path(arm, np.array([T_goal]), np.zeros(6))
    err = info.value
    assert err.reason == 'out_of_reach' and err.details['waypoint'] == 0
    _check_details(err, arm, T_goal)
    assert err.details['position_error'] > 0.2


def test_moving_into_a_singularity_is_refused_leaving_it_is_not():
    arm = mover6()
    q_from = np.array([0.2, 0.3, 0.4, 0.5, 0.4, 0.1])
    q_to = np.array([0.2, 0.3, 0.4, 0.5, 0.0005, 0.1])  # q5 -> 0: axes 4 and 6 align
    s = np.linspace(0.0, 1.0, 30)[:, None]
    poses = fk_batch(arm, q_from + s * (q_to - q_from))
    with pytest.raises(UnreachableError) as info:
        solve_path(arm, poses, q_from, max_condition=1000.0)
    err = info.value
    assert err.reason == 'singularity' and err.details['condition'] > 1000.0
    k = err.details['waypoint']
    assert condition_number(arm, err.details['closest_q']) <= 1000.0
    _check_details(err, arm, poses[k])
    # Without the check the same path solves; reversed it leaves the singular pose.
    solve_path(arm, poses, q_from)
    solve_path(arm, poses[::-1].copy(), q_to, max_condition=1000.0)
    # The earliest failure is the one reported: later an unreachable pose or a jump.
    for extra in (pose_from_xyzabc(0.9, 0.0, 0.3, 0.0, 0.0, 0.0), fk(arm, q_from + 1.0)):
        with pytest.raises(UnreachableError) as later:
            solve_path(arm, np.concatenate([poses, extra[None]]), q_from, max_condition=1000.0)
        assert later.value.reason == 'singularity' and later.value.details['waypoint'] == k


def test_numeric_fallback_for_arms_without_a_spherical_wrist():
    arm = ur5()
    q_start = np.array([0.4, -1.2, 1.0, -0.5, 0.8, 0.3])
    q_end = q_start + np.array([0.3, 0.2, -0.2, 0.1, 0.2, -0.3])
    s = np.linspace(0.0, 1.0, 15)[:, None]
    joint_path = q_start + s * (q_end - q_start)
    sol = solve_path(arm, fk_batch(arm, joint_path), q_start)
    assert sol.method == 'numeric'
    np.testing.assert_allclose(sol.q, joint_path, atol=1e-5)
    np.testing.assert_allclose(fk_batch(arm, sol.q), fk_batch(arm, joint_path), atol=1e-6)


@pytest.mark.parametrize('kwargs, match', [
    ({'poses': np.full((2, 4, 4), np.nan)}, 'non-finite'),
    ({'poses': np.tile(np.diag([1.0, 1.0, 1.1, 1.0]), (2, 1, 1))}, 'orthonormal'),
    ({'poses': np.zeros((0, 4, 4))}, 'empty'),
    ({'poses': np.eye(4)}, 'shape'),
    ({'q_start': np.zeros(7)}, 'q_start'),
    ({'max_joint_step': -0.1}, 'max_joint_step'),
    ({'max_condition': float('nan')}, 'max_condition'),
    ({'position_tol': 0.0}, 'position_tol'),
])
def test_bad_input_raises(kwargs, match):
    arm = mover6()
    args = {'poses': fk(arm, np.zeros(6))[None], 'q_start': np.zeros(6)}
    args.update(kwargs)
    poses, q_start = args.pop('poses'), args.pop('q_start')
    with pytest.raises(InvalidInputError, match=match):
        solve_path(arm, poses, q_start, **args)


def test_single_turn_arms():
    assert single_turn(mover6()) and single_turn(mover6('hardware'))
    assert not single_turn(minibot())          # +-pi: a full turn of range
    with pytest.raises(InvalidInputError, match='full turn'):
        branch_steps(minibot(), np.zeros((2, 8, 6)), np.ones((2, 8), dtype=bool))
    with pytest.raises(InvalidInputError, match='mask'):
        branch_steps(mover6(), np.zeros((2, 8, 6)), np.ones((3, 8), dtype=bool))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 31), st.sampled_from(['within_90_deg', 'hardware']))
def test_branch_steps_match_aliasing_branch_by_branch(seed, limit_set):
    # The batched table against nearest_alias on each pair of branches, as the per-waypoint
    # rule does it; values in the 1e-9 rad slack outside a limit included.
    arm = mover6(limit_set)
    rng = np.random.default_rng(seed)
    Q = rng.uniform(arm.lower, arm.upper, (5, 8, 6))
    edge = rng.random(Q.shape) < 0.15
    Q[edge] = np.where(rng.random(Q.shape) < 0.5, arm.lower - 5e-10, arm.upper + 5e-10)[edge]
    valid = rng.random((5, 8)) < 0.7
    steps = branch_steps(arm, Q, valid)
    assert steps.shape == (4, 8, 8)
    for k in range(4):
        for a in range(8):
            for c in range(8):
                q = nearest_alias(arm, Q[k + 1, c], Q[k, a])
                inside = np.all((q >= arm.lower - 1e-9) & (q <= arm.upper + 1e-9))
                want = np.abs(q - Q[k, a]).max() if valid[k + 1, c] and inside else np.inf
                assert steps[k, a, c] == pytest.approx(want, abs=1e-12)


def _walk_reference(arm, poses, q_start):
    """Choose each waypoint's branch one pose at a time, nearest the previous choice."""
    geo = wrist_geometry(arm)
    q_prev, out = q_start, []
    for T in poses:
        cand, ok = solve_candidates(arm, geo, T[None], q_prev[None])
        sols = nearest_alias(arm, cand[0][ok[0]], q_prev)
        sols = sols[np.all((sols >= arm.lower - 1e-9) & (sols <= arm.upper + 1e-9), axis=1)]
        q_prev = sols[np.argmin(np.abs(sols - q_prev).max(axis=1))]
        out.append(q_prev)
    return np.array(out)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2 ** 31))
def test_table_walk_chooses_as_waypoint_by_waypoint(seed):
    # Random pose paths with turns in orientation (branches come close), from a random start:
    # the batched walk picks what the per-waypoint rule picks.
    arm = mover6('hardware')
    rng = np.random.default_rng(seed)
    q_start = rng.uniform(arm.lower * 0.9, arm.upper * 0.9)
    knots = q_start + np.cumsum(rng.uniform(-0.3, 0.3, (4, 6)), axis=0)
    knots = np.clip(knots, arm.lower, arm.upper)
    s = np.linspace(0.0, 1.0, 20)[:, None]
    joint_path = np.concatenate([q_start + s * (knots[0] - q_start)]
                                + [a + s[1:] * (b - a) for a, b in zip(knots, knots[1:])])
    poses = fk_batch(arm, joint_path)
    try:
        sol = solve_path(arm, poses, q_start, max_joint_step=0.5)
    except UnreachableError:
        assume(False)
    assume(not sol.self_motion.any())
    np.testing.assert_allclose(sol.q, _walk_reference(arm, poses, q_start), atol=1e-12)
    np.testing.assert_allclose(sol.joint_step[1:],
                               np.abs(np.diff(sol.q, axis=0)).max(axis=1), atol=1e-12)
