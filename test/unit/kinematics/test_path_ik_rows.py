"""
Path IK writes its rows in bulk; the branch choice stays waypoint by waypoint (issue 32, round 3).

The table walk collects the branches it takes and writes them into the solution in one call
(before the long way reads them, and at the end); when nothing was inserted the rows are the
waypoints' copied in one call. The choice itself is local: each waypoint takes the branch
nearest the one before (checked here against the closed form's branches of each pose).
"""

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.ik_closed_form import ik_closed_form
from mover6_control.kinematics.path_ik import solve_path
from mover6_control.motion import paths
import numpy as np

ARM = mover6()


def linear_poses(q_a, q_b, n):
    """Return the n poses after the first of a straight tool line from FK(q_a) to FK(q_b)."""
    return paths.linear_curve(fk(ARM, q_a), fk(ARM, q_b), n=n).poses[1:]


def test_each_row_of_a_long_path_is_the_branch_nearest_the_row_before():
    q_a = np.array([0.3, 0.4, 0.5, 0.2, 0.6, -0.3])
    q_b = np.array([-0.4, 0.6, 0.3, -0.3, 0.9, 0.4])
    P = linear_poses(q_a, q_b, 1000)
    sol = solve_path(ARM, P, q_a, max_joint_step=0.05, max_condition=1000.0)
    assert len(sol.q) == len(P)
    assert not sol.inserted.any() and not sol.self_motion.any()
    np.testing.assert_array_equal(sol.poses, P)
    # The rows are the solution's own (not views of the caller's poses).
    assert not np.shares_memory(sol.poses, P)
    assert sol.position_error.max() < 1e-9 and sol.orientation_error.max() < 1e-9
    assert sol.max_joint_step <= 0.05
    previous = np.vstack([q_a, sol.q[:-1]])
    for k in range(0, len(P), 7):
        branches = ik_closed_form(ARM, P[k], within_limits=True, q_ref=previous[k])
        steps = np.abs(branches - previous[k]).max(axis=1)
        taken = np.abs(sol.q[k] - previous[k]).max()
        assert taken <= steps.min() + 1e-12, k
        assert np.abs(branches - sol.q[k]).max(axis=1).min() < 1e-9, k


def test_rows_inserted_by_a_bridge_keep_their_place():
    # Few waypoints, a small joint step: the stretches are followed more finely.
    q_a = np.array([0.2, 0.3, 0.6, 0.1, 0.7, -0.2])
    q_b = np.array([-0.3, 0.5, 0.4, -0.2, 0.9, 0.3])
    path = paths.linear_curve(fk(ARM, q_a), fk(ARM, q_b), n=5)
    sol = solve_path(ARM, path.poses[1:], q_a, max_joint_step=0.05,
                     pose_between=lambda k, s: path.between(k + 1, s))
    assert sol.inserted.any()
    np.testing.assert_array_equal(sol.poses[~sol.inserted], path.poses[1:])
    assert len(sol.q) == len(path.poses) - 1 + sol.inserted.sum()
    assert sol.max_joint_step <= 0.05
    np.testing.assert_array_equal(sol.q[~sol.inserted][-1], sol.q[-1])
