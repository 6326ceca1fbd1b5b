"""
The goal lines of the README's "Sending goals" section, as a user would copy them.

Read by the planning, collision and end-to-end tests: each line parsed by the goal command's
own parser and pose conversion and planned from q = 0 (where every start-up begins) by the
planner core with the planner node's defaults, under the default limits (within_90_deg).
"""

import os
import shlex

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.planning.planner_core import plan_path_goal, plan_pose_goal, PlannerSettings
from mover6_control.planning.via_joint import plan_via_path_goal
from mover6_control.tools.goal_convention import parabola_peak, poses_from_numbers
from mover6_control.tools.goal_parser import build_parser
import numpy as np
from source_tree import ROOT

README = os.path.join(ROOT, 'README.md')
ARM = mover6('within_90_deg')
HOME = np.zeros(6)
# The planner node's defaults (config/planner.yaml): the shape of /pose_goal and /path_goal.
DEFAULT_MOTION = 'linear'
DEFAULT_PATH_MOTION = 'spline'


def readme_goal_lines():
    """Return the ``./run.sh goal ...`` lines of the README's "Sending goals" section."""
    with open(README, encoding='utf-8') as f:
        text = f.read()
    section = text.split('## Sending goals', 1)[1].split('\n## ', 1)[0]
    return [line.split('#', 1)[0].strip() for line in section.splitlines()
            if line.startswith('./run.sh goal ')]


def goal_argv(line):
    """Return the goal command's arguments of a README line, in its plain form made explicit."""
    argv = shlex.split(line)[2:]
    if argv and argv[0] not in ('pose', 'path', 'joints', 'stop'):
        argv = ['pose'] + argv     # the plain form: goal X Y Z A B C
    return argv


def plan_readme_goal(argv, q_start=HOME, arm=ARM):
    """Plan a parsed README goal as the goal command and the planner node would, for ``arm``."""
    args = build_parser().parse_args(argv)
    if args.command == 'pose':
        T_goal = poses_from_numbers(args.numbers, args.quat, arm, args.absolute)[0]
        if args.peak_height is not None:
            # As GoalClient.send_pose: the goal command's own peak pose, on /path_goal/parabolic.
            T_peak = parabola_peak(fk(arm, q_start), T_goal, args.peak_height)
            return plan_path_goal(arm, q_start, T_peak[None], T_goal, 'parabolic',
                                  PlannerSettings())
        return plan_pose_goal(arm, q_start, T_goal, args.motion or DEFAULT_MOTION,
                              PlannerSettings())
    targets = poses_from_numbers(args.via + args.numbers, args.quat, arm, args.absolute)
    if args.shape == 'joint':       # /path_goal/joint: the via-point joint move
        return plan_via_path_goal(arm, q_start, targets[:-1], targets[-1], PlannerSettings())
    return plan_path_goal(arm, q_start, targets[:-1], targets[-1],
                          args.shape or DEFAULT_PATH_MOTION, PlannerSettings())
