"""A planned motion as goal points, the plan's text and the teach check."""

from mover6_control.control.timed_plan import peak, timed_spline, Timing
from mover6_control.kinematics.arm import mover6
from mover6_control.programs.limits import JointLimits
from mover6_control.programs.program_file import load_program
from mover6_control.programs.program_plan import plan_program
from mover6_control.programs.program_run import (plan_lines, stretched, TEACH_MAX_AGE,
                                                 teach_refusal, TEACH_SPEED, timed_points)
import numpy as np
from program_examples import pick_and_place, write_program

ARM = mover6()
LIMITS = JointLimits.of(ARM)


def test_the_points_keep_the_controllers_interpolation_on_the_plan_within_the_limits(tmp_path):
    plan = plan_program(ARM, load_program(ARM, write_program(tmp_path, pick_and_place(1))),
                        np.zeros(6))
    for motion in plan.motions():
        points = timed_points(motion)
        assert points.t[-1] == motion.duration and np.all(np.diff(points.t) > 0)
        np.testing.assert_allclose(points.qd[-1], 0.0)
        spline = timed_spline(motion.q[0], np.zeros(6), points.q, Timing(points.t, points.qd))
        for j in range(6):
            lo, hi = peak(spline, 1, j)
            assert max(-lo, hi) <= LIMITS.velocity[j] * (1 + 1e-6)
            lo, hi = peak(spline, 2, j)
            assert max(-lo, hi) <= LIMITS.acceleration[j] * (1 + 1e-6)
        t = np.linspace(0.0, motion.duration, 500)
        q, _, _ = motion.trajectory.sample(t)
        assert np.abs(spline(t) - q).max() < 1e-4         # [rad] on the planned motion
        slow = stretched(points, 2.0)
        assert slow.t[-1] == 2.0 * points.t[-1]
        np.testing.assert_allclose(slow.qd, points.qd / 2.0)


def test_the_plan_reads_one_line_per_motion_and_action(tmp_path):
    plan = plan_program(ARM, load_program(ARM, write_program(tmp_path, pick_and_place(1))),
                        np.zeros(6))
    lines = plan_lines(plan)
    assert len(lines) == 1 + len(plan.items)
    assert '3 lin above_pick > 4 ptp above_place > 5 lin place' in lines[3]


def test_a_point_is_taught_only_from_fresh_states_at_rest():
    assert teach_refusal(None, None) == 'no joint states heard'
    assert 'stale' in teach_refusal(TEACH_MAX_AGE * 2, np.zeros(6))
    assert 'moves' in teach_refusal(0.01, np.full(6, TEACH_SPEED * 2))
    assert teach_refusal(0.01, np.zeros(6)) is None
