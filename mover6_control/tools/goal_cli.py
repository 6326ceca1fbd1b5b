"""
The goal command line's client: send a goal, follow the motion, exit 0 only when the arm arrived.

``GoalClient`` is the node: it sends pose, path and joint goals (and ~/stop), and follows the
planner's and the controller's status about its own goal only (the planner's status names it by
its stamp, ``goal_stamp``; the controller's by the ``goal_id`` the planner gave it) until the
motion ends. It is composed of parts, each given what it uses in its constructor:
``readiness.Spinner``, ``readiness.LatestStatus`` (what it hears), ``readiness.Readiness``,
``goal_follower.MotionFollower`` (one goal followed to its end), ``PlannerParameters`` and
``GoalStopper``. ``run`` runs one command line with it, ``main`` is ``ros2 run mover6_control
goal``. The command's syntax, its examples, the goal conventions and the exit codes are its
``--help``: ``tools/goal_parser.py``.
"""

import sys
from typing import Callable, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.errors import Mover6Error
from mover6_control.kinematics.arm import ArmModel, mover6
from mover6_control.kinematics.forward import fk
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.runtime.names import namespace_from
from mover6_control.nodes.runtime.qos import STATUS_READER_QOS
from mover6_control.tools.goal_convention import (EXIT_ARRIVED, EXIT_FAILED, EXIT_NO_NODES,
                                                  EXIT_REFUSED, format_outcome, Outcome,
                                                  parabola_peak, poses_from_numbers)
from mover6_control.tools.goal_follower import MotionFollower
from mover6_control.tools.goal_parser import build_parser
from mover6_control.tools.readiness import LatestStatus, Readiness, Spinner, status_values
from mover6_control.values import JointDemand
import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.publisher import Publisher
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
from std_srvs.srv import Trigger

# [s] longest wait for the planner's ~/stop service (no planner: the controller is stopped).
PLANNER_STOP_WAIT = 2.0


class PlannerParameters:
    """Set the planner's parameters (``node``'s parameter client of ``planner_node``)."""

    def __init__(self, node: Node, spinner: Spinner, planner_node: str) -> None:
        self.client = AsyncParameterClient(node, planner_node)
        self.spinner = spinner

    def apply(self, params: dict, timeout: float = 10.0) -> Optional[str]:
        """Set planner parameters (e.g. motion); return an error text or None."""
        if not params:
            return None
        if not self.client.wait_for_services(timeout_sec=timeout):
            return 'the planner parameter service is not available'
        future = self.client.set_parameters(
            [Parameter(name, value=value) for name, value in params.items()])
        if not self.spinner.spin_until(future.done, timeout):
            return 'setting planner parameters timed out'
        for name, result in zip(params, future.result().results):
            if not result.successful:
                return f'planner refused parameter {name}: {result.reason}'
        return None


class GoalStopper:
    """Call the planner's and the controller's ~/stop (clients of ``node``)."""

    def __init__(self, node: Node, spinner: Spinner, planner_node: str,
                 controller_node: str) -> None:
        self.spinner = spinner
        self.stop_client = node.create_client(Trigger, f'{controller_node}/stop')
        self.planner_stop_client = node.create_client(Trigger, f'{planner_node}/stop')

    def stop(self, timeout: float = 10.0) -> tuple[bool, str, bool]:
        """
        Call the planner's ~/stop, then the controller's; return (success, message, was it there).

        The planner's first, so that no goal it is still planning goes out after the stop; a
        planner that is not running is no error (the controller's stop is what stops the arm).
        """
        planner_note = ''
        if self.planner_stop_client.wait_for_service(timeout_sec=PLANNER_STOP_WAIT):
            future = self.planner_stop_client.call_async(Trigger.Request())
            if self.spinner.spin_until(future.done, timeout):
                planner_note = f'; planner: {future.result().message}'
        ok, text, available = self.stop_controller(timeout)
        return ok, text + planner_note, available

    def stop_controller(self, timeout: float = 10.0) -> tuple[bool, str, bool]:
        """Call the controller's ~/stop service; return (success, its message, was it there)."""
        if not self.stop_client.wait_for_service(timeout_sec=timeout):
            return False, ('the controller stop service is not available (is the controller '
                           'running?)'), False
        future = self.stop_client.call_async(Trigger.Request())
        if not self.spinner.spin_until(future.done, timeout):
            return False, 'stop service call timed out', True
        return future.result().success, future.result().message, True


def _latest_field(name):
    """Return a property reading and writing ``self.latest.<name>``."""
    def get(self):
        return getattr(self.latest, name)

    def put(self, value):
        setattr(self.latest, name, value)
    return property(get, put, doc=f'The latest ``{name}`` (``readiness.LatestStatus``).')


class GoalClient(Node):
    """A node that sends goals and follows the planner's and controller's status."""

    def __init__(self, name: str = 'goal_client', planner_node: str = 'planner',
                 controller_node: str = 'controller') -> None:
        super().__init__(name)
        self.arm = mover6()
        self.latest = LatestStatus(self.arm.joint_names)
        self.spinner = Spinner(self)
        self.pose_pub = self.create_publisher(PoseStamped, 'pose_goal', 10)
        self.path_pub = self.create_publisher(PoseArray, 'path_goal', 10)
        self.demands_pub = self.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.shape_pubs = {}         # topic -> publisher of the goal topics of one shape
        self.readiness = Readiness(self.spinner, self.latest, self.pose_pub, self)
        self.follower = MotionFollower(self.spinner, self.latest, self.arm)
        self.planner_params = PlannerParameters(self, self.spinner, planner_node)
        self.stopper = GoalStopper(self, self.spinner, planner_node, controller_node)
        # Depth 10: a status (such as the controller's 'rejected' report) is not overwritten by
        # the next one before it is read.
        self.create_subscription(DiagnosticStatus, 'planner/status', self.on_planner,
                                 STATUS_READER_QOS)
        self.create_subscription(DiagnosticStatus, 'controller/status', self.on_controller,
                                 STATUS_READER_QOS)
        self.create_subscription(JointState, 'joint_states', self.on_joint_states, 10)
        self.create_subscription(Float32MultiArray, 'joint_demands', self.on_demands, 10)

    q = _latest_field('q')
    planner_status = _latest_field('planner_status')
    controller_status = _latest_field('controller_status')
    last_demands = _latest_field('last_demands')
    rejection = _latest_field('rejection')
    goal_id = _latest_field('goal_id')

    # --- what it hears (kept by ``latest``; a subclass may hear more) ----------------------

    def on_planner(self, msg: DiagnosticStatus) -> None:
        """Keep the planner's latest status."""
        self.latest.on_planner(msg)

    def on_controller(self, msg: DiagnosticStatus) -> None:
        """Keep the controller's latest status, and note when it rejected a demand."""
        self.latest.on_controller(msg)

    def on_joint_states(self, msg: JointState) -> None:
        """Keep the latest joint positions."""
        self.latest.on_joint_states(msg)

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Keep the latest joint demands (the planner's output)."""
        self.latest.on_demands(msg)

    # --- the parts' work, by the names its users call --------------------------------------

    @staticmethod
    def values(msg: Optional[DiagnosticStatus]) -> dict:
        """Return a status message's values as a dict (empty for None)."""
        return status_values(msg)

    def spin_until(self, predicate: Callable[[], bool], timeout: float,
                   tick: Optional[Callable[[], None]] = None) -> bool:
        """Spin until ``predicate()`` is true or ``timeout`` [s] passes (``Spinner``)."""
        return self.spinner.spin_until(predicate, timeout, tick)

    def wait_ready(self, timeout: float = 30.0, need_planner: bool = True,
                   steady: float = 1.0) -> Optional[str]:
        """Wait for the nodes a goal needs (``Readiness.wait_ready``); None when ready."""
        return self.readiness.wait_ready(timeout, need_planner, steady)

    def on_topic(self, topic: str, publisher_node: str, subscriber_node: str) -> bool:
        """Return True when the graph shows both nodes on ``topic`` (``Readiness``)."""
        return self.readiness.on_topic(topic, publisher_node, subscriber_node)

    def set_planner_parameters(self, params: dict, timeout: float = 10.0) -> Optional[str]:
        """Set planner parameters (``PlannerParameters.apply``); return an error text or None."""
        return self.planner_params.apply(params, timeout)

    def stop(self, timeout: float = 10.0) -> tuple[bool, str, bool]:
        """Stop the planner's goals and the arm (``GoalStopper.stop``)."""
        return self.stopper.stop(timeout)

    def stop_controller(self, timeout: float = 10.0) -> tuple[bool, str, bool]:
        """Call the controller's ~/stop (``GoalStopper.stop_controller``)."""
        return self.stopper.stop_controller(timeout)

    def run_goal(self, publish: Callable[[], None], **kwargs: object) -> Outcome:
        """Publish a goal with ``publish()`` and follow it to its end (``MotionFollower.run``)."""
        return self.follower.run(publish, **kwargs)

    # --- goals -----------------------------------------------------------------------------

    def publisher(self, msg_type: type, topic: str) -> Publisher:
        """Return the publisher of ``topic`` (made on first use)."""
        if topic not in self.shape_pubs:
            self.shape_pubs[topic] = self.create_publisher(msg_type, topic, 10)
        return self.shape_pubs[topic]

    def send_pose(self, T_goal: np.ndarray, frame_id: str = 'base_link',
                  motion: Optional[str] = None, peak_height: Optional[float] = None,
                  **kwargs: object) -> Outcome:
        """
        Send a pose goal and follow it; see ``run_goal``.

        ``motion`` None goes to /pose_goal (the planner's default shape), otherwise to
        /pose_goal/<motion>. A ``peak_height`` [m] makes it a parabola through the mid-point of
        the present tool position and the goal raised by that much along base z, sent by its
        peak pose on /path_goal/parabolic.
        """
        if peak_height is not None:
            if self.q is None:
                return Outcome(EXIT_NO_NODES, 'no /joint_states: the start pose is unknown')
            T_peak = parabola_peak(fk(self.arm, self.q), T_goal, peak_height)
            return self.send_path(np.stack([T_peak, T_goal]), frame_id, shape='parabolic',
                                  **kwargs)
        msg = PoseStamped()
        msg.header.frame_id = frame_id
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.pose = conversions.matrix_to_pose(T_goal)
        pub = self.pose_pub if motion is None else self.publisher(PoseStamped,
                                                                  f'pose_goal/{motion}')
        self.wait_matched(pub)
        return self.run_goal(lambda: pub.publish(msg), T_goal=T_goal, stamp=msg.header.stamp,
                             **kwargs)

    def send_path(self, poses: np.ndarray, frame_id: str = 'base_link',
                  shape: Optional[str] = None, **kwargs: object) -> Outcome:
        """Send a path goal (via poses then the goal, (k, 4, 4)) and follow it."""
        msg = PoseArray()
        msg.header.frame_id = frame_id
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.poses = [conversions.matrix_to_pose(T) for T in poses]
        pub = self.path_pub if shape is None else self.publisher(PoseArray, f'path_goal/{shape}')
        self.wait_matched(pub)
        return self.run_goal(lambda: pub.publish(msg), T_goal=poses[-1], stamp=msg.header.stamp,
                             **kwargs)

    def wait_matched(self, pub: Publisher, timeout: float = 10.0) -> None:
        """Wait until ``pub`` is matched with a reader (a topic made just now is not yet)."""
        self.spin_until(lambda: pub.get_subscription_count() > 0, timeout)

    def send_joints(self, Q: np.ndarray, profile: str = '', **kwargs: object) -> Outcome:
        """Send joint waypoints (n, 6) to /joint_demands (timed by ``profile``) and follow them."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        stamp = self.get_clock().now().to_msg()
        goal_id = f'{self.get_name()}-{stamp.sec}.{stamp.nanosec:09d}'
        msg = demand_messages.make_demands(Q, goal_id, profile)
        if not self.spin_until(lambda: self.demands_pub.get_subscription_count() > 0, 10.0):
            return Outcome(EXIT_NO_NODES, 'no subscriber on /joint_demands')
        return self.run_goal(lambda: self.demands_pub.publish(msg), planned=False,
                             goal_id=goal_id,
                             T_goal=fk(self.arm, Q[-1]), **kwargs)


# --- command line ----------------------------------------------------------------------------

def run(argv: Sequence[str], client: Optional[GoalClient] = None,
        out: Callable[[str], None] = print) -> int:
    """Run the command line ``argv``; return the exit code."""
    if argv and argv[0] not in ('pose', 'path', 'joints', 'stop', '-h', '--help'):
        argv = ['pose'] + list(argv)  # the plain form: goal X Y Z A B C
    args = build_parser().parse_args(argv)
    if args.command is None:
        build_parser().print_help()
        return EXIT_REFUSED
    say = (lambda text: None) if args.quiet else out
    try:
        if args.command == 'pose':
            targets = poses_from_numbers(args.numbers, args.quat, client_arm(client),
                                         args.absolute)
            if len(targets) != 1:
                raise Mover6Error('pose takes exactly one pose')
        elif args.command == 'path':
            targets = poses_from_numbers(args.via + args.numbers, args.quat, client_arm(client),
                                         args.absolute)
        elif args.command == 'joints':
            if len(args.numbers) % 6:
                raise Mover6Error(f'joints takes 6 angles per waypoint, got {len(args.numbers)}')
            targets = JointDemand.from_rows(args.numbers, 6).positions
    except Mover6Error as err:
        out(f'RESULT refused: {err}')
        return EXIT_REFUSED
    except ValueError as err:
        out(f'RESULT refused: {err}')
        return EXIT_REFUSED

    if args.command == 'stop':
        ok, text, available = client.stop()
        out(f'RESULT {"stopped" if ok else "failed"}: {text}')
        return EXIT_ARRIVED if ok else EXIT_FAILED if available else EXIT_NO_NODES

    problem = client.wait_ready(timeout=30.0, need_planner=args.command != 'joints')
    if problem:
        out(f'RESULT failed: {problem}')
        return EXIT_NO_NODES
    kwargs = {'timeout': args.timeout, 'progress': say}
    profile = getattr(args, 'profile', None)
    frame = args.frame + (f' profile {profile}' if profile else '')   # goal_profile_from_header
    if args.command == 'pose':
        if args.peak_height is not None and args.motion not in (None, 'parabolic'):
            out(f'RESULT refused: --peak-height is for parabolic moves, not {args.motion}')
            return EXIT_REFUSED
        say(f'sending pose goal {np.round(targets[0][:3, 3], 4).tolist()} m')
        outcome = client.send_pose(targets[0], frame_id=frame, motion=args.motion,
                                   peak_height=args.peak_height, **kwargs)
    elif args.command == 'path':
        say(f'sending path goal with {len(targets) - 1} via poses')
        outcome = client.send_path(targets, frame_id=frame, shape=args.shape, **kwargs)
    else:
        say(f'sending {len(targets)} joint waypoints')
        outcome = client.send_joints(targets, profile=profile or '', **kwargs)
    convention = None
    if args.command in ('pose', 'path'):
        ref = (0.0, 0.0, 0.0)
        if not args.quat:
            ref = tuple((getattr(args, 'via', []) + args.numbers)[-3:])
        convention = (client_arm(client), args.absolute or args.quat, ref)
    out(format_outcome(outcome, convention))
    return outcome.code


def client_arm(client: Optional[GoalClient]) -> ArmModel:
    """Return the arm of ``client`` (the Mover6 when there is no client)."""
    return getattr(client, 'arm', None) or mover6()


def main(args: Optional[list[str]] = None) -> None:
    """Entry point of ``ros2 run mover6_control goal``."""
    argv = sys.argv[1:] if args is None else list(args)
    if argv[:1] == ['jog']:                  # goal jog: the keyboard teleop
        from mover6_control.tools import teleop
        sys.exit(teleop.main(argv[1:]))
    ros_args = []
    if '--ros-args' in argv:
        idx = argv.index('--ros-args')
        argv, ros_args = argv[:idx], argv[idx:]
    namespace, argv = namespace_from(argv)
    if namespace is None:             # refused with the naming rule it breaks
        sys.exit(EXIT_REFUSED)
    if namespace != '/':        # every topic, service and action of the CLI follows it
        ros_args = (ros_args or ['--ros-args']) + ['-r', f'__ns:={namespace}']
    rclpy.init(args=['goal'] + ros_args)
    client = None
    code = EXIT_FAILED
    try:
        client = GoalClient()
        code = run(argv, client)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = EXIT_FAILED
    finally:
        if client is not None:
            client.destroy_node()
        rclpy.try_shutdown()
    sys.exit(code)


if __name__ == '__main__':
    main()
