"""Reachability verdicts: the Mover6 report's example goal in both readings, and every reason."""

from mover6_control.errors import InvalidInputError, REASONS
from mover6_control.kinematics.arm import from_dh, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.reachability import check_path, check_pose, Verdict
from mover6_control.kinematics.rotations import euler_zyx_to_matrix, pose_error, pose_from_xyzabc
import numpy as np
import pytest

REPORT_IK_GOAL = (0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)   # X Y Z [m], A B C [rad]


def mover6_report_goal(reading):
    """Return the Mover6 report's example goal read absolutely or relatively (its MATLAB)."""
    T = pose_from_xyzabc(*REPORT_IK_GOAL)
    if reading == 'relative':
        T[:3, :3] = fk(mover6(), np.zeros(6))[:3, :3] @ euler_zyx_to_matrix(*REPORT_IK_GOAL[3:])
    return T


def _check_closest(verdict, arm, T):
    assert isinstance(verdict, Verdict) and verdict.reason in REASONS
    pos, rot = pose_error(verdict.closest_pose, T)
    assert verdict.position_error == pytest.approx(pos, abs=1e-12)
    assert verdict.orientation_error == pytest.approx(rot, abs=1e-12)
    assert verdict.message and verdict.message[0].isalpha()


def test_mover6_report_goal_read_absolutely_is_outside_the_90_deg_limits():
    arm = mover6()
    T = mover6_report_goal('absolute')
    v = check_pose(arm, T)
    assert not v.reachable and v.reason == 'joint_limits' and v.q is None
    assert 'joint3=1.6544' in v.message and 'outside' in v.message
    _check_closest(v, arm, T)
    assert arm.within_limits(v.details['closest_q'])
    np.testing.assert_allclose(v.closest_pose, fk(arm, v.details['closest_q']), atol=1e-12)
    # Closer than the Mover6 report's constrained optimiser got (6.7 mm, its eq. 21-22 answer).
    assert 0.0 < v.position_error < 0.0067
    assert not arm.within_limits(v.details['q_outside_limits'])


def test_mover6_report_goal_read_relatively_is_exactly_reachable():
    arm = mover6()
    T = mover6_report_goal('relative')
    v = check_pose(arm, T)
    assert v.reachable and v.reason == 'reachable'
    assert arm.within_limits(v.q)
    assert v.position_error < 1e-12 and v.orientation_error < 1e-9
    _check_closest(v, arm, T)
    assert len(v.solutions) == 1


@pytest.mark.parametrize('reading', ['absolute', 'relative'])
def test_mover6_report_goal_is_outside_the_hardware_limits_either_way(reading):
    v = check_pose(mover6('hardware'), mover6_report_goal(reading))
    assert v.reason == 'joint_limits' and 'joint2' in v.message


def test_out_of_reach():
    arm = mover6()
    T = pose_from_xyzabc(0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    v = check_pose(arm, T)
    assert v.reason == 'out_of_reach' and not v.reachable
    _check_closest(v, arm, T)
    # |p_tip| <= sum of the link lengths (0.7875 m); straight up reaches z = 0.7275 m.
    assert 1.5 - 0.7875 < v.position_error < 1.5 - 0.7275 + 0.05


def test_pose_reachable_only_at_a_singularity():
    arm = mover6()
    T = fk(arm, np.zeros(6))                  # home: q5 = 0, the only in-limit solution
    assert check_pose(arm, T).reachable
    v = check_pose(arm, T, max_condition=1000.0)
    assert v.reason == 'singularity' and not v.reachable
    assert v.position_error < 1e-12 and v.details['condition'] > 1000.0
    _check_closest(v, arm, T)


def test_q_ref_picks_the_nearest_solution():
    arm = mover6('hardware')
    q = np.array([0.3, 0.2, -0.4, 1.2, 0.5, 1.2])     # its wrist flip is inside the limits
    v = check_pose(arm, fk(arm, q), q_ref=q)
    assert v.reachable and len(v.solutions) > 1
    np.testing.assert_allclose(v.q, q, atol=1e-9)


def test_numeric_arm_verdicts():
    arm = from_dh([0, -0.425, -0.39225, 0, 0, 0], [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0],
                  [0.089159, 0, 0, 0.10915, 0.09465, 0.0823], name='ur5',
                  lower=[-3.0, -3.0, -2.0, -3.0, -3.0, -3.0],
                  upper=[3.0, 0.0, 2.0, 3.0, 3.0, 3.0])
    q = np.array([0.4, -1.2, 1.0, -0.5, 0.8, 0.3])
    assert check_pose(arm, fk(arm, q), q_ref=q).reachable
    v = check_pose(arm, pose_from_xyzabc(2.0, 0.0, 0.2, 0.0, 0.0, 0.0))
    assert v.reason == 'out_of_reach'


def test_path_verdicts():
    arm = mover6()
    q0 = np.array([0.1, 0.2, 0.3, 0.2, 0.5, 0.1])
    s = np.linspace(0.0, 1.0, 10)[:, None]
    joint_path = q0 + s * np.array([0.2, 0.1, -0.2, 0.1, 0.1, 0.2])
    ok = check_path(arm, fk_batch(arm, joint_path), q0, max_condition=1000.0)
    assert ok.reachable and ok.q.shape == (10, 6)
    np.testing.assert_allclose(ok.q, joint_path, atol=1e-8)
    T_goal = mover6_report_goal('absolute')
    bad = check_path(arm, np.array([fk(arm, q0), T_goal]), q0, max_joint_step=10.0)
    assert bad.reason == 'joint_limits' and bad.waypoint == 1 and not bad.reachable
    _check_closest(bad, arm, T_goal)
    jump = check_path(arm, np.array([fk(arm, q0), fk(arm, q0 + [1.0, 0, 0, 0, 0, 0])]), q0)
    assert jump.reason == 'discontinuity' and jump.waypoint == 1


def test_bad_input_raises():
    arm = mover6()
    with pytest.raises(InvalidInputError, match='orthonormal'):
        check_pose(arm, np.diag([1.0, 1.0, 3.0, 1.0]))
    with pytest.raises(InvalidInputError, match='q_ref'):
        check_pose(arm, np.eye(4), q_ref=[0.0, float('nan'), 0, 0, 0, 0])
    with pytest.raises(InvalidInputError, match='non-finite'):
        check_path(arm, np.full((3, 4, 4), np.inf), np.zeros(6))
