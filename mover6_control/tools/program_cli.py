"""
The program command line: check, run and teach programs of moves on the running stack.

``ros2 run mover6_control program check FILE`` loads the program (``programs.program_file``)
and plans it whole (``programs.program_plan``) from the arm's current /joint_states (or
``--start``), then prints the plan or the refusal with the file's line and the reason.
``run FILE`` plans it the same way from the arm at rest, then sends each motion to the
controller's ``~/follow_joint_trajectory`` action as timed points (``programs.program_run``),
waits for each result, runs gripper steps through the driver's ``~/gripper_cmd``
(GripperCommand; a stack without that server refuses a program with a gripper step) and
waits for inputs on ``/InputChannels``; Ctrl-C cancels the running motion (the controller
stops the arm with its usual deceleration) and reports the step it stopped at. ``--speed`` and
``speed``, ``pause``, ``resume`` set the controller's speed scaling (``~/speed_scaling_input``,
control_msgs/SpeedScalingFactor; 0 pauses): the path is the same at every speed. ``teach NAME
FILE`` stores the arm's current joint positions, at rest and from fresh joint states, as point
NAME of the points file FILE.

Exit codes: 0 done (or checked), 1 a motion or step failed or was stopped, 2 refused (the file,
the plan, a point not taught), 3 no stack (no joint states or no controller action).
"""

import argparse
import json
import sys
import time
from typing import Optional, Sequence, TextIO

from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import SpeedScalingFactor
from mover6_control.control.timed_plan import peak, timed_spline, Timing
from mover6_control.hardware.gripper import STROKE
from mover6_control.kinematics.arm import ArmModel, mover6
from mover6_control.nodes.messages import conversions
from mover6_control.programs.limits import JointLimits
from mover6_control.programs.points import load_points, Point
from mover6_control.programs.program_error import ProgramError
from mover6_control.programs.program_file import load_program
from mover6_control.programs.program_plan import Action, Motion, plan_program, PlannedProgram
from mover6_control.programs.program_run import (end_of, plan_lines, reached_error,
                                                 refusal_lines, stretched, teach_refusal,
                                                 timed_points, TimedPoints)
from mover6_control.programs.steps import GripperStep, WaitStep
from mover6_control.tools.goal_convention import (EXIT_ARRIVED, EXIT_FAILED, EXIT_NO_NODES,
                                                  EXIT_REFUSED)
from mover6_control.tools.readiness import Spinner
import numpy as np
import rclpy
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_msgs.msg import UInt8MultiArray
from trajectory_msgs.msg import JointTrajectoryPoint

STATES_WAIT = 10.0      # [s] longest wait for the first joint states
SERVER_WAIT = 10.0      # [s] for the controller's action server
GRIPPER_WAIT = 2.0      # [s] for the driver's gripper server (none: the stack has no gripper)
RESULT_MARGIN = 30.0    # [s] a motion's result is awaited its duration and this
GRIPPER_TIMEOUT = 10.0  # [s] a gripper step's result
CANCEL_WAIT = 10.0      # [s] a canceled motion's end
SCALING_MATCH = 2.0     # [s] for the controller to subscribe the speed scaling input
FJT_NAME = 'controller/follow_joint_trajectory'
GRIPPER_NAME = 'driver/gripper_cmd'
SCALING_TOPIC = 'controller/speed_scaling_input'
ACTION_SUCCEEDED = 4    # action_msgs/GoalStatus STATUS_SUCCEEDED


class ProgramClient(Node):
    """The node of the command line: joint states and inputs in, goals and scaling out."""

    def __init__(self, arm: ArmModel) -> None:
        """Subscribe the joint states and inputs, make the action clients and the publisher."""
        super().__init__('program')
        self.arm = arm
        self.spinner = Spinner(self)
        self.q = self.qd = None
        self.heard = None              # time.monotonic() of the latest joint states
        self.inputs = None
        self.trajectory = ActionClient(self, FollowJointTrajectory, FJT_NAME)
        self.gripper = ActionClient(self, GripperCommand, GRIPPER_NAME)
        self.scaling = self.create_publisher(SpeedScalingFactor, SCALING_TOPIC, 10)
        self.create_subscription(JointState, 'joint_states', self.on_joint_states, 10)
        self.create_subscription(UInt8MultiArray, 'InputChannels', self.on_inputs, 10)

    def on_joint_states(self, msg: JointState) -> None:
        """Keep the latest joint positions and velocities, and when they came."""
        try:
            self.q, self.qd = conversions.joint_state_from_msg(msg, self.arm.joint_names)
        except Exception:  # noqa: B902 - a malformed message is not a reading
            return
        self.heard = time.monotonic()

    def on_inputs(self, msg: UInt8MultiArray) -> None:
        """Keep the latest digital inputs."""
        self.inputs = list(msg.data)

    def age(self) -> Optional[float]:
        """Return how old the latest joint states are [s] (None: none heard)."""
        return None if self.heard is None else time.monotonic() - self.heard

    def fresh_q(self, timeout: float = STATES_WAIT) -> Optional[np.ndarray]:
        """Return joint positions heard after this call (None after ``timeout``)."""
        self.heard = None
        if not self.spinner.spin_until(lambda: self.heard is not None, timeout):
            return None
        return self.q.copy()

    def wait_future(self, future: Future, timeout: float) -> bool:
        """Spin until ``future`` is done or ``timeout`` [s]; return whether it is done."""
        return self.spinner.spin_until(future.done, timeout)

    def set_scaling(self, factor: float) -> Optional[str]:
        """Publish a speed scaling factor once the controller listens; None, or why not."""
        if not self.spinner.spin_until(lambda: self.scaling.get_subscription_count() > 0,
                                       SCALING_MATCH):
            return (f'nothing subscribes {self.scaling.topic_name} (the controller takes no '
                    'speed scaling input)')
        self.scaling.publish(SpeedScalingFactor(factor=float(factor)))
        return None


def slowdown(arm: ArmModel, motion: Motion, points: TimedPoints) -> float:
    """
    Return how much slower (>= 1) ``points`` must run for the controller to keep their timing.

    The controller's own check (``control.timed_plan``: the exact peaks of its cubic pieces
    against the joint speeds and ``a_max``); 1 when they hold. Stretching time by ``k`` divides
    the speeds by ``k`` and the accelerations by ``k**2``.
    """
    limits = JointLimits.of(arm)
    spline = timed_spline(end_of_start(motion), np.zeros(arm.n_joints), points.q,
                          Timing(points.t, points.qd))
    worst = 1.0
    for j in range(arm.n_joints):
        for order, limit, power in ((1, limits.velocity[j], 1.0),
                                    (2, limits.acceleration[j], 0.5)):
            lo, hi = peak(spline, order, j)
            worst = max(worst, (max(-lo, hi) / limit) ** power)
    return worst * (1.0 + 1e-6) if worst > 1.0 else 1.0


def end_of_start(motion: Motion) -> np.ndarray:
    """Return the joint positions (n,) a motion starts at."""
    return np.array(motion.q[0], dtype=float)


def trajectory_goal(arm: ArmModel, points: TimedPoints) -> FollowJointTrajectory.Goal:
    """Return the goal of one motion's timed points, with the arm's joint names."""
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = list(arm.joint_names)
    for t, q, qd in zip(points.t, points.q, points.qd):
        point = JointTrajectoryPoint(positions=[float(v) for v in q],
                                     velocities=[float(v) for v in qd])
        point.time_from_start = Duration(nanoseconds=int(round(t * 1e9))).to_msg()
        goal.trajectory.points.append(point)
    return goal


class ProgramRunner:
    """Run a planned program on the stack, motion by motion; record what each one reached."""

    def __init__(self, client: ProgramClient, plan: PlannedProgram, step: bool = False,
                 out=sys.stdout) -> None:
        """Keep the client, the plan, whether to wait for Enter before each item."""
        self.client = client
        self.plan = plan
        self.step = step
        self.out = out
        self.active = None           # the running goal's handle
        self.results = []            # one dict per motion

    def say(self, text: str) -> None:
        """Print a line of the run."""
        print(text, file=self.out, flush=True)

    def run(self) -> int:
        """Run every item; return the exit code. Ctrl-C cancels the running motion."""
        steps = self.plan.program.run
        started = time.monotonic()
        for item in self.plan.items:
            index = item.indices[-1] if isinstance(item, Motion) else item.index
            if self.step:
                input(f'[Enter] step {index + 1} {steps[index].step.name} ')
            try:
                ok = (self.motion(item) if isinstance(item, Motion) else self.action(item))
            except KeyboardInterrupt:
                self.stop(index)
                return EXIT_FAILED
            if not ok:
                return EXIT_FAILED
        self.say(f'done: {len(self.results)} motions in {time.monotonic() - started:.2f} s '
                 f'(planned {self.plan.motion_time:.2f} s of motion)')
        return EXIT_ARRIVED

    def motion(self, motion: Motion) -> bool:
        """Send one motion, wait for its result, record the error at its end."""
        client, steps = self.client, self.plan.program.run
        names = ', '.join(steps[i].step.name for i in motion.indices)
        points = timed_points(motion)
        factor = slowdown(client.arm, motion, points)
        if factor > 1.0:
            points = stretched(points, factor)
            self.say(f'step {motion.indices[0] + 1}: {factor:.3f} times slower than planned '
                     "(the controller's interpolation between the points)")
        sent = time.monotonic()
        future = client.trajectory.send_goal_async(trajectory_goal(client.arm, points))
        if not client.wait_future(future, SERVER_WAIT) or not future.result().accepted:
            self.say(f'step {motion.indices[0] + 1} ({names}): the controller did not take it')
            return False
        self.active = future.result()
        result = self.active.get_result_async()
        if not client.wait_future(result, motion.duration + RESULT_MARGIN):
            self.say(f'step {motion.indices[0] + 1} ({names}): no result in time: stopping')
            self.stop(motion.indices[-1])
            return False
        self.active = None
        took = time.monotonic() - sent
        answer = result.result()
        planned = motion.duration * factor
        q = client.fresh_q(2.0)
        target = end_of(motion)
        joint, tool = reached_error(client.arm, q, target) if q is not None else (np.nan, np.nan)
        ok = answer.status == ACTION_SUCCEEDED and answer.result.error_code == 0
        self.results.append({'steps': [i + 1 for i in motion.indices], 'names': names,
                             'target': steps[motion.indices[-1]].step.target.label,
                             'planned': planned, 'measured': took,
                             'joint_error': joint, 'tool_error': tool, 'ok': ok,
                             'q': None if q is None else q.tolist()})
        self.say(f'step {motion.indices[-1] + 1} {names}: '
                 f'{"reached" if ok else "FAILED"} in {took:.2f} s (planned '
                 f'{planned:.2f} s), joint error {joint:.5f} rad, tool {tool * 1e3:.2f} mm'
                 + ('' if ok else f': {answer.result.error_string}'))
        return ok

    def action(self, item: Action) -> bool:
        """Run a step that does not move the arm: speed (planned in), gripper, wait."""
        step, label = item.step, f'step {item.index + 1} {item.step.name}'
        if isinstance(step, GripperStep):
            return self.grip(step, label)
        if isinstance(step, WaitStep):
            return self.wait(step, label)
        self.say(f'{label}: the moves after it are planned at this fraction')
        return True

    def grip(self, step: GripperStep, label: str) -> bool:
        """Open or close the gripper through the driver's GripperCommand; wait for it."""
        goal = GripperCommand.Goal()
        goal.command.position = 0.0 if step.action == 'close' else float(STROKE)
        future = self.client.gripper.send_goal_async(goal)
        if not self.client.wait_future(future, SERVER_WAIT) or not future.result().accepted:
            self.say(f'{label}: the gripper did not take it')
            return False
        result = future.result().get_result_async()
        if not self.client.wait_future(result, GRIPPER_TIMEOUT):
            self.say(f'{label}: no result in {GRIPPER_TIMEOUT:g} s')
            return False
        ok = result.result().status == ACTION_SUCCEEDED
        self.say(f'{label}: {"done" if ok else "FAILED"}')
        return ok

    def wait(self, step: WaitStep, label: str) -> bool:
        """Wait a time, or for an input to reach its state within its timeout."""
        if not step.channel:
            deadline = time.monotonic() + step.seconds
            self.client.spinner.spin_until(lambda: time.monotonic() >= deadline,
                                           step.seconds + 1.0)
            self.say(f'{label}: done')
            return True
        want = step.state == 'high'

        def reached():
            data = self.client.inputs
            return data is not None and len(data) >= step.channel and (
                bool(data[step.channel - 1]) == want)

        ok = self.client.spinner.spin_until(reached, step.timeout)
        self.say(f'{label}: {"done" if ok else f"not in {step.timeout:g} s"}')
        return ok

    def stop(self, index: int) -> None:
        """Cancel the running motion (the arm decelerates and holds); say where it stopped."""
        if self.active is not None:
            cancel = self.active.cancel_goal_async()
            self.client.wait_future(cancel, CANCEL_WAIT)
            self.client.wait_future(self.active.get_result_async(), CANCEL_WAIT)
        self.say(f'stopped at step {index + 1} {self.plan.program.run[index].step.name}')


def build_parser() -> argparse.ArgumentParser:
    """Return the command line's parser."""
    parser = argparse.ArgumentParser(
        prog='program', description='Check, run and teach programs of moves (docs/programs.md).')
    sub = parser.add_subparsers(dest='command', required=True)
    check = sub.add_parser('check', help='plan a program and print the plan or the refusal')
    run = sub.add_parser('run', help='plan a program, then run it on the stack')
    for p in (check, run):
        p.add_argument('file', help='the program file (YAML)')
        p.add_argument('--points', help='the points file (default: the program\'s "points")')
    check.add_argument('--start', type=float, nargs=6, metavar='Q',
                       help='plan from these joint positions [rad] (default: /joint_states)')
    check.add_argument('--gripper', choices=('yes', 'no'),
                       help='plan as for a stack with or without a gripper (default: ask it)')
    run.add_argument('--speed', type=float,
                     help="set the controller's speed scaling to this fraction first (0-1]")
    run.add_argument('--step', action='store_true', help='wait for Enter before each step')
    run.add_argument('--report', help="write the motions' results to this file (JSON)")
    teach = sub.add_parser('teach', help='store the current joint positions as a point')
    teach.add_argument('name', help='the point name (letters, digits, underscores)')
    teach.add_argument('file', nargs='?', default='points.yaml', help='the points file')
    teach.add_argument('--replace', action='store_true', help='replace a point of that name')
    speed = sub.add_parser('speed', help="set the controller's speed scaling (0: pause)")
    speed.add_argument('factor', type=float)
    sub.add_parser('pause', help='speed scaling 0: the arm stops on its path')
    sub.add_parser('resume', help='speed scaling 1')
    return parser


def _plan(client: ProgramClient, args, has_gripper: bool, start) -> PlannedProgram:
    program = load_program(client.arm, args.file, has_gripper=has_gripper,
                           points_path=args.points)
    return plan_program(client.arm, program, start)


def _start_at_rest(client: ProgramClient) -> tuple[Optional[np.ndarray], Optional[str]]:
    q = client.fresh_q()
    if q is None:
        return None, f'no /joint_states in {STATES_WAIT:g} s'
    problem = teach_refusal(client.age(), client.qd)
    return q, problem


def run(argv: Sequence[str], client: Optional[ProgramClient] = None,
        out: TextIO = sys.stdout) -> int:
    """Run one command line; return its exit code."""
    args = build_parser().parse_args(list(argv))
    client = client or ProgramClient(mover6())
    say = lambda text: print(text, file=out, flush=True)  # noqa: E731
    if args.command in ('speed', 'pause', 'resume'):
        factor = {'pause': 0.0, 'resume': 1.0}.get(args.command, getattr(args, 'factor', 1.0))
        if not 0.0 <= factor <= 1.0:
            say(f'refused: a speed scaling factor is 0-1, got {factor:g}')
            return EXIT_REFUSED
        problem = client.set_scaling(factor)
        say(problem or f'speed scaling {factor:g}')
        return EXIT_NO_NODES if problem else EXIT_ARRIVED
    if args.command == 'teach':
        return _teach(client, args, say)
    if args.command == 'check' and args.start is not None:
        start = np.array(args.start)
    else:
        start, problem = _start_at_rest(client)
        if start is None:
            say(f'no stack: {problem}')
            return EXIT_NO_NODES
        if problem and args.command == 'run':
            say(f'refused: {problem}')
            return EXIT_REFUSED
    if args.command == 'check' and args.gripper is not None:
        has_gripper = args.gripper == 'yes'
    else:
        has_gripper = client.gripper.wait_for_server(timeout_sec=GRIPPER_WAIT)
    try:
        plan = _plan(client, args, has_gripper, start)
    except ProgramError as err:
        for line in refusal_lines(err):
            say(line)
        return EXIT_REFUSED
    for line in plan_lines(plan):
        say(line)
    if args.command == 'check':
        return EXIT_ARRIVED
    if not client.trajectory.wait_for_server(timeout_sec=SERVER_WAIT):
        say(f'no stack: no action server {FJT_NAME}')
        return EXIT_NO_NODES
    if args.speed is not None:
        if not 0.0 < args.speed <= 1.0:
            say(f'refused: --speed is a fraction (0, 1], got {args.speed:g}')
            return EXIT_REFUSED
        problem = client.set_scaling(args.speed)
        if problem:
            say(f'refused: --speed {args.speed:g}: {problem}')
            return EXIT_REFUSED
    runner = ProgramRunner(client, plan, args.step, out)
    code = runner.run()
    if args.report:
        with open(args.report, 'w', encoding='utf-8') as f:
            json.dump({'planned': plan.motion_time, 'motions': runner.results}, f, indent=1)
    return code


def _teach(client: ProgramClient, args, say) -> int:
    q = client.fresh_q()
    if q is None:
        say(f'no stack: no /joint_states in {STATES_WAIT:g} s')
        return EXIT_NO_NODES
    problem = teach_refusal(client.age(), client.qd)
    try:
        if problem:
            raise ProgramError(args.file, 0, f'point "{args.name}" not taught: {problem}',
                               'teach_refused')
        book = load_points(client.arm, args.file)
        point = Point.of(client.arm, args.name, q, args.file)
        book.taught(point, replace=args.replace).save()
    except ProgramError as err:
        for line in refusal_lines(err):
            say(line)
        return EXIT_REFUSED
    say(f'taught {point.name} in {args.file}: joints '
        + ' '.join(f'{v:.4f}' for v in point.joints) + ' pose '
        + ' '.join(f'{v:.4f}' for v in point.pose))
    return EXIT_ARRIVED


def main(args: Optional[list[str]] = None) -> None:
    """Run ``ros2 run mover6_control program ...``; exit with its code."""
    argv = rclpy.utilities.remove_ros_args(sys.argv if args is None else args)[1:]
    rclpy.init(args=args)
    client = ProgramClient(mover6())
    try:
        code = run(argv, client)
    except KeyboardInterrupt:
        code = EXIT_FAILED
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
    sys.exit(code)


if __name__ == '__main__':
    main()
