"""
The goal command line: send a goal, follow the motion, exit 0 only when the arm arrived.

Poses are the flange (link6) in base_link: X Y Z [m], then A B C [rad] as the Mover6 report
writes goals: ZYX Euler angles applied to the flange's home orientation, R = R_home Rz(A) Ry(B)
Rx(C), R_home the flange orientation at q = 0 (the flange z axis along +x), so ``0 0 0`` keeps
the home orientation. With ``--absolute`` A B C are base-frame ZYX angles, R = Rz(A) Ry(B) Rx(C)
(home is then 0 1.5708 0). ``--quat`` takes a base-frame quaternion. Examples::

    goal 0.445 0 0.4425 0 0 0                         # the Mover6 report's linear example
    goal 0.1 0.1 0.2 0 1.5708 0                       # the Mover6 report's IK example
    goal 0.445 0 0.4425 0 1.5708 0 --absolute         # base-frame angles: the home orientation
    goal pose 0.30 -0.08 0.32 0 0 0 --motion parabolic --peak-height 0.02
    goal pose --quat 0.30 0.05 0.36 0 0.7071068 0 0.7071068
    goal path --shape spline --via 0.32 -0.03 0.36 0 0 0 0.29 0.10 0.35 0 0 0
    goal path --shape joint --via 0.32 0.0 0.38 0 0 0 0.30 0.08 0.34 0 0 0
    goal pose 0.30 0.05 0.36 0 0 0 --profile quintic  # this goal timed by the 3-4-5 law
    goal joints 0.2 0.1 0.3 0 0.4 0                   # straight to /joint_demands
    goal stop                                         # the planner's and controller's ~/stop
    goal jog                                          # keyboard jogging (tools/teleop.py)

The RESULT line gives the pose reached, in the goal's own convention. ``--motion`` and
``--shape`` pick the topic of that shape (/pose_goal/parabolic, /path_goal/arc ...);
``--peak-height`` sends the parabola by its peak pose (/path_goal/parabolic, the Mover6 report's
eq. 12); ``--shape joint`` moves in joint space through one via pose (/path_goal/joint, the
Jacobians and trajectories report's via-point polynomial). ``--profile`` asks the controller to
time this goal's motion with that law (the goal's frame id ``base_link profile <name>``; the
demand's label ``... profile <name>``). No node's parameters change. The command follows only
its own goal: the planner's status names it by its stamp (``goal_stamp``), and the controller's
status by the ``goal_id`` the planner gave it.

Exit codes: 0 arrived, 1 motion failed (fault, aborted, stopped, timed out), 2 goal refused or
malformed, 3 nodes not found.
"""

import argparse

from mover6_control.parameters import PROFILES


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of the goal command."""
    parser = argparse.ArgumentParser(
        prog='goal', description=__doc__.split('\n\n')[0],
        epilog=__doc__.split('\n\n', 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument('--timeout', type=float, default=60.0,
                        help='seconds to wait for the motion to finish (default 60)')
    common.add_argument('--frame', default='base_link', help='frame of the goal (base_link)')
    common.add_argument('--quiet', action='store_true', help='print only the result line')
    common.add_argument('--namespace', default='',
                        help='the namespace of the stack to talk to (e.g. /arm1; default none)')
    common.add_argument('--profile', choices=PROFILES,
                        help="the controller's law for this goal only (default: its profile "
                             'parameter, which does not change)')
    angles = argparse.ArgumentParser(add_help=False)
    angles.add_argument('--absolute', action='store_true',
                        help='A B C are base-frame ZYX angles, R = Rz(A) Ry(B) Rx(C) (home is '
                             '0 1.5708 0), not relative to the home orientation')
    sub = parser.add_subparsers(dest='command')
    pose = sub.add_parser('pose', parents=[common, angles],
                          help='move the tool to a pose (/pose_goal)')
    pose.add_argument('numbers', type=float, nargs='+', metavar='N',
                      help='X Y Z A B C, or X Y Z QX QY QZ QW with --quat')
    pose.add_argument('--quat', action='store_true', help='orientation as a quaternion')
    pose.add_argument('--motion', choices=('linear', 'parabolic', 'joint'),
                      help="the goal's shape (its topic /pose_goal/<shape>; default: the "
                           "planner's motion parameter)")
    pose.add_argument('--peak-height', type=float,
                      help='parabolic peak height [m] (sent as the peak pose on '
                           "/path_goal/parabolic; default: the planner's peak_height)")
    path = sub.add_parser('path', parents=[common, angles],
                          help='move through via poses to the last pose (/path_goal)')
    # nargs='*': '--via' takes every number after it, goal included (the README's spelling).
    path.add_argument('numbers', type=float, nargs='*', metavar='N',
                      help='poses one after another; the last one is the goal')
    path.add_argument('--via', type=float, nargs='+', default=[], metavar='N',
                      help='via poses (alternative spelling: put them before the goal)')
    path.add_argument('--quat', action='store_true', help='orientations as quaternions')
    path.add_argument('--shape', choices=('spline', 'arc', 'parabolic', 'joint'),
                      help="the path's shape (its topic /path_goal/<shape>; parabolic: one via "
                           'pose, the peak; joint: one via pose, a joint move; default: the '
                           "planner's path_motion parameter)")
    joints = sub.add_parser('joints', parents=[common],
                            help='send joint waypoints straight to /joint_demands')
    joints.add_argument('numbers', type=float, nargs='+', metavar='Q',
                        help='6 joint angles [rad] per waypoint')
    sub.add_parser('stop', parents=[common],
                   help='drop the goals the planner still plans, decelerate and hold (the '
                        "planner's and the controller's ~/stop services)")
    # Listed for --help; main() hands 'goal jog ...' to the teleop before parsing.
    sub.add_parser('jog', help='drive the tool live from the keyboard (the teleop; its own '
                               'keys and options: goal jog --help)')
    return parser
