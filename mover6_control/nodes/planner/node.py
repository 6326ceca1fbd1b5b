"""
The planner node: pose goals in, joint waypoints (N x 6) out on /joint_demands.

Subscribes /pose_goal (geometry_msgs/PoseStamped), /path_goal (geometry_msgs/PoseArray) and
/joint_states; publishes /joint_demands (std_msgs/Float32MultiArray) and /planner/status
(diagnostic_msgs/DiagnosticStatus, transient local). All the planning is in
``mover6_control.planning.planner_core``; this node converts, calls it and reports.

A goal's shape travels with the goal, never through the parameters: /pose_goal/linear,
/pose_goal/parabolic (peak ``peak_height`` above the mid-point), /pose_goal/joint, and
/path_goal/spline, /path_goal/arc, /path_goal/parabolic (PoseArray [peak, goal]: the Mover6
report's eq. 12) plan that shape; /path_goal/joint (PoseArray [via, goal]) plans a joint move
through the via pose, the Jacobians and trajectories report's via-point polynomial
(``planning.via_joint``); /pose_goal and /path_goal plan the default shapes, the
``motion`` and ``path_motion`` parameters. A goal whose frame id is ``base_link profile <name>``
asks the controller to time its motion with that profile: the demand carries it (``waypoints
goal <goal_id> profile <name>``) and the predicted duration is timed with it; no parameter of
either node changes. Each goal gets a ``goal_id``: its header stamp and
the planner's goal counter, ``<sec>.<nanosec>-<seq>`` (``ros2 topic echo`` shows both). The
status about a goal carries it (``goal_id``, ``goal_stamp``, ``goal_seq``) and so do the
demands planned for it (``layout.dim[0].label`` = ``waypoints goal <goal_id>``), which the
controller echoes in its status next to its ``motion_id``.

Every status says whether the planner is ready (value ``state``): ``waiting_for_states`` until
the first valid /joint_states (and again while a goal finds them older than ``state_timeout``),
``ready`` from then on. A goal that comes before that waits up to ``state_wait_timeout`` for
fresh states (status ``result`` ``waiting_for_states``), and only then is refused. Goals are
planned one after another in a planning thread, so the node goes on reading states, answering
its ~/stop service (std_srvs/Trigger: drop every goal received so far that is still waiting,
being planned, or waiting for the controller's answer) and the controller's answers while a goal
is planned. Each goal ends with one of these results on the status: ``planned`` (the demand went
out), ``refused`` (reason: why the goal cannot be planned, ``no_controller``, or the
controller's answer: ``controller_refused`` or ``controller_not_ready`` with its reason, or
``stopped``), or ``failed`` (``not_acknowledged``: no controller answered; ``superseded``: a
later demand reached the controller first). The handshake with the controller:
``handshake``.

The node is built from parts, each a class given what it uses: the latest states
(``joint_states``), the goal counter (``goal_book``), the status (``status_publisher``), the
delivery of demands (``delivery``, with its ``handshake``) and the planning thread
(``planning_thread``); this module holds the callbacks.
"""

import dataclasses
import sys
import time
from typing import Callable, Optional

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.collision.checker import CollisionChecker
from mover6_control.control.status import PlannerState
from mover6_control.errors import Mover6Error
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.planner.delivery import DemandDelivery
from mover6_control.nodes.planner.goal_book import GoalBook
from mover6_control.nodes.planner.joint_states import LatestJointStates
from mover6_control.nodes.planner.planning_thread import PlanningThread
from mover6_control.nodes.planner.status_publisher import PlannerStatus
from mover6_control.nodes.runtime import params, shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.nodes.runtime.node_configs import (check_where_it_stands,
                                                       planner_settings_from_parameters,
                                                       standing_check)
from mover6_control.nodes.runtime.qos import LATEST_READER_QOS, STATUS_QOS
from mover6_control.parameters import PLANNER
from mover6_control.planning.planner_core import (check_path_shape, PATH_MOTIONS,
                                                  plan_path_goal, plan_pose_goal, PlannerSettings,
                                                  POSE_MOTIONS)
from mover6_control.planning.via_joint import plan_via_path_goal
from mover6_control.realtime import steady_interpreter
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from std_srvs.srv import Trigger

# Longest wait [s] at shutdown for the goal being planned to finish.
PLANNING_JOIN_TIMEOUT = 5.0


class PlannerNode(Node):
    """Plan pose and path goals into joint waypoints, refuse what cannot be reached."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the arm and the parts, start the planning thread."""
        super().__init__('planner', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        # Refuses invalid values, each and as the planner's settings, and collision parameters
        # that put the arm in collision where it stands, at start and later.
        self.standing, self.states = standing_check(), None
        params.declare(self, PLANNER, self.check_config, guard=self.guard)
        limit_set = self.get_parameter('limit_set').value
        self.arm = mover6(limit_set)
        self._checker = None     # the collision checker of the latest settings
        self.closed = False
        self.states = LatestJointStates(self.arm, lambda: now_ns(self.get_clock()))
        self.goals = GoalBook()
        self.status = PlannerStatus(
            self.create_publisher(DiagnosticStatus, 'planner/status', STATUS_QOS),
            self.get_logger())
        self.delivery = DemandDelivery(
            self, self.guard, self.arm, self.status, self.goals,
            lambda: self.get_parameter('match_timeout').value, lambda: not self.closed)
        self.planning = PlanningThread(
            self.states, self.status, self.delivery, self.goals, self.settings,
            lambda name: self.get_parameter(name).value, self.get_logger())

        # Raw: 100 messages a second only need keeping; one is converted when a goal needs it.
        self.guard.subscription(JointState, 'joint_states', self.on_joint_states,
                                LATEST_READER_QOS, raw=True)
        self.guard.subscription(PoseStamped, 'pose_goal', self.on_pose_goal, 10)
        self.guard.subscription(PoseArray, 'path_goal', self.on_path_goal, 10)
        for shape in POSE_MOTIONS:
            self.guard.subscription(PoseStamped, f'pose_goal/{shape}',
                                    lambda msg, shape=shape: self.on_pose_goal(msg, shape), 10)
        for shape in PATH_MOTIONS:
            self.guard.subscription(PoseArray, f'path_goal/{shape}',
                                    lambda msg, shape=shape: self.on_path_goal(msg, shape), 10)
        self.guard.subscription(PoseArray, 'path_goal/joint', self.on_via_joint_goal, 10)
        self.guard.service(Trigger, '~/stop', self.on_stop)
        self.status.publish('WARN', 'waiting for /joint_states', {})
        self.planning.start()
        self.get_logger().info(
            f'planner: motion={self.get_parameter("motion").value}, '
            f'limit_set={limit_set}, frame={self.get_parameter("frame_id").value}; '
            'waiting for /joint_states')

    def check_config(self, get: Callable[[str], object]) -> None:
        """
        Raise saying why the parameters of ``get(name)`` are no valid planner configuration.

        The planner's settings, and the collision parameters where the arm stands (the latest
        /joint_states; at start the start configuration): ``node_configs``.
        """
        planner_settings_from_parameters(get)
        started = self.states is not None
        check_where_it_stands(self.standing, get, self.states.q if started else None,
                              (lambda n: self.get_parameter(n).value) if started else None)

    def frame_id(self) -> str:
        """Return the frame goals must be given in."""
        return self.get_parameter('frame_id').value

    def settings(self) -> PlannerSettings:
        """Return the planner settings from the current parameters."""
        return planner_settings_from_parameters(lambda n: self.get_parameter(n).value)

    def checker(self, settings: PlannerSettings) -> Optional[CollisionChecker]:
        """Return the collision checker of ``settings`` (kept while they do not change)."""
        if not settings.collision.enabled:
            return None
        if self._checker is None or self._checker.settings != settings.collision:
            self._checker = CollisionChecker(self.arm, settings.collision)
        return self._checker

    # --- inputs (executor thread) ----------------------------------------------------------

    def on_joint_states(self, raw: bytes) -> None:
        """
        Keep the latest /joint_states as it came (``LatestJointStates``).

        Only while the planner is not ready is a message converted, to say ready on the first
        valid one.
        """
        self.states.keep(raw)
        if self.status.state != PlannerState.READY and self.states.q is not None:
            self.status.set_state(PlannerState.READY)

    def on_pose_goal(self, msg: PoseStamped, motion: Optional[str] = None) -> None:
        """Plan a pose goal with ``motion``, by default the shape of the ``motion`` parameter."""
        motion = motion or self.get_parameter('motion').value

        def prepare():
            T = conversions.pose_goal_from_msg(msg, self.frame_id())
            return lambda q, settings: plan_pose_goal(self.arm, q, T, motion, settings,
                                                      self.checker(settings))
        self.submit(msg.header, motion, prepare)

    def on_path_goal(self, msg: PoseArray, motion: Optional[str] = None) -> None:
        """Plan a path goal (via poses then the goal) with ``motion`` (or ``path_motion``)."""
        motion = motion or self.get_parameter('path_motion').value
        self.submit(msg.header, motion, lambda: self.path_planner(
            msg, motion, lambda q, vias, goal, settings: plan_path_goal(
                self.arm, q, vias, goal, motion, settings, self.checker(settings))))

    def on_via_joint_goal(self, msg: PoseArray) -> None:
        """Plan a joint move through one via pose (PoseArray [via, goal]): ``via_joint``."""
        self.submit(msg.header, 'joint', lambda: self.path_planner(
            msg, 'joint', lambda q, vias, goal, settings: plan_via_path_goal(
                self.arm, q, vias, goal, settings, self.checker(settings))))

    def path_planner(self, msg: PoseArray, motion: str, plan: Callable) -> Callable:
        """
        Check a PoseArray goal of shape ``motion``; return its plan function ``f(q, settings)``.

        The cheap checks come first: the via count of the shape (``check_path_shape``) before a
        single pose is converted, then every pose's form; reachability only once planned.
        """
        if msg.poses:
            check_path_shape(motion, len(msg.poses) - 1)
        poses = conversions.path_goal_from_msg(msg, self.frame_id())
        return lambda q, settings: plan(q, poses[:-1], poses[-1], settings)

    def on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Drop every goal received so far that waits, is planned or waits for its answer."""
        stopped_seq = self.goals.stop()
        response.success = True
        response.message = (f'goals up to {stopped_seq} dropped: none of them is planned '
                            "or sent from now on (the controller's ~/stop stops the arm)")
        self.get_logger().info(f'stop: {response.message}')
        self.delivery.stop()
        return response

    def submit(self, header: Header, motion: str, prepare: Callable[[], Callable]) -> None:
        """
        Give a goal its id, check its form, and queue it for the planning thread.

        ``prepare()`` checks the message (cheap: no kinematics) and returns its plan function
        ``f(q, settings)``; a malformed goal is refused here at once, even while another one is
        being planned.
        """
        goal = self.goals.new_goal(header)
        try:
            profile = conversions.goal_profile_from_header(header)
            if profile:
                goal = dataclasses.replace(goal, profile=profile)   # forwarded with the demand
            plan_fn = prepare()
        except (Mover6Error, ValueError) as err:
            self.status.refuse(motion, str(err), 'invalid_goal', {}, goal)
            raise                   # refused: the guard counts it too
        self.planning.put(goal, motion, plan_fn, time.monotonic())

    def destroy_node(self) -> None:
        """End the planning thread (a goal being planned finishes first), then the node."""
        self.closed = True
        self.planning.close(PLANNING_JOIN_TIMEOUT)
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Run the planner node until Ctrl-C, SIGTERM or shutdown (one or more signals: exit 0)."""
    # What is loaded now (rclpy, numpy, MuJoCo) is never scanned by a full collection: one took
    # 35 ms in the middle of a goal's plan (bench planner's tail). The switch interval stays.
    steady_interpreter(sys.getswitchinterval())
    shutdown.run_node(PlannerNode, args)


if __name__ == '__main__':
    main()
