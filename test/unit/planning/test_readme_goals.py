"""
Every pose and path goal of the README's "Sending goals" section plans from home.

The lines are read from the README as a user would copy them, parsed by the goal command's own
parser and pose conversion, and planned from q = 0 (where every start-up begins) by the planner
core with the planner node's defaults, under the default limits (within_90_deg).
"""

from mover6_control.errors import UnreachableError
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest
from readme_goals import ARM, goal_argv, HOME, plan_readme_goal, readme_goal_lines


def test_the_readme_has_the_goal_lines():
    """The section is found, with its pose, parabolic and path examples."""
    lines = readme_goal_lines()
    assert len(lines) >= 8, lines
    assert any('--motion parabolic' in line for line in lines)
    assert any(goal_argv(line)[0] == 'path' for line in lines)


@pytest.mark.parametrize('line', [line for line in readme_goal_lines()
                                  if goal_argv(line)[0] in ('pose', 'path')])
def test_every_readme_goal_plans_from_home(line):
    """Each pose or path goal of the README plans from q = 0 and ends at its goal."""
    plan = plan_readme_goal(goal_argv(line))
    assert plan.n_waypoints >= 2
    assert np.allclose(plan.q[0], HOME)
    assert all(ARM.within_limits(q) for q in plan.q), line
    assert plan.final_position_error <= 1e-3 and plan.final_orientation_error <= 0.01


def test_the_issues_parabolic_peak_of_4_cm_needs_the_hardware_limits():
    """
    The issue's parabolic example (peak 0.04 m) from home: the README shows 0.02 m, and why.

    Along that parabola the wrist's two branches need q4 down to about -2.0 rad (q5 <= 0) or up
    to about 2.45 rad (q5 >= 0): no wrist choice keeps it within +-90 deg, so the default limits
    refuse it (the largest peak they plan from home is about 0.032 m); the hardware limits
    (q4 +-2.443 rad) plan it.
    """
    line = [line for line in readme_goal_lines() if '--motion parabolic' in line][0]
    argv = goal_argv(line)
    argv[argv.index('--peak-height') + 1] = '0.04'
    with pytest.raises(UnreachableError) as err:
        plan_readme_goal(argv)
    assert err.value.reason == 'joint_limits'
    plan = plan_readme_goal(argv, arm=mover6('hardware'))
    assert plan.final_position_error <= 1e-3 and plan.q[:, 3].min() < -np.pi / 2
