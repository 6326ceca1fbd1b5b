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
its ~/stop service (std_srvs/Trigger: drop every goal received so far that is still waiting or
being planned, and stop sending their demands again) and the controller's status while a goal is
planned. Each goal ends with one of these results on the status: ``planned`` (the demand went
out), ``refused`` (reason: why the goal cannot be planned, or ``controller_refused`` with the
controller's reason, or ``stopped``), or ``failed`` (``not_acknowledged``: no controller named
the goal after ``RESENDS`` more sends).
"""

import queue
import threading
import time
from typing import Callable, Optional

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.control.status import PlannerResult, PlannerState
from mover6_control.errors import Mover6Error
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.rotations import matrix_to_euler_zyx
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.planner_delivery import CONTROLLER_STATUS_QOS, DemandDelivery
from mover6_control.nodes.planner_thread import PlanningThread, READY, WAITING
from mover6_control.nodes.runtime import params, shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.nodes.runtime.node_configs import planner_settings_from_parameters
from mover6_control.nodes.runtime.qos import LATEST_READER_QOS, STATUS_QOS
from mover6_control.parameters import PLANNER
from mover6_control.planning.planner_core import (check_path_shape, PATH_MOTIONS,
                                                  plan_path_goal, plan_pose_goal, POSE_MOTIONS)
from mover6_control.planning.via_joint import plan_via_path_goal
import numpy as np
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray, Header
from std_srvs.srv import Trigger


class PlannerNode(PlanningThread, DemandDelivery, Node):
    """Plan pose and path goals into joint waypoints, refuse what cannot be reached."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the arm, start the topics and the planning thread."""
        super().__init__('planner', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        # Refuses invalid values, each and as the planner's settings, at start and later.
        params.declare(self, PLANNER, planner_settings_from_parameters, guard=self.guard)
        limit_set = self.get_parameter('limit_set').value
        self.arm = mover6(limit_set)
        self.state = WAITING
        self.states_came = threading.Event()   # set by every /joint_states
        self.states = None       # (serialized /joint_states, node clock [ns] at arrival): latest
        self._converted = None   # (serialized message, its positions): the latest converted
        self.goal_seq = 0
        self.stopped_seq = 0         # goals up to this seq were dropped by ~/stop
        self.lock = threading.Lock()           # unconfirmed, state
        self.status_lock = threading.Lock()    # one status publication at a time
        self.unconfirmed = {}        # goal_id -> Unconfirmed
        self.controller_values = {}
        self._checker = None     # the collision checker of the latest settings
        self.running = True
        self.jobs = queue.SimpleQueue()   # goals not yet planned; None: the node closes
        self.demands_pub = self.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.status_pub = self.create_publisher(DiagnosticStatus, 'planner/status', STATUS_QOS)
        # Raw: 100 messages a second only need keeping; one is converted when a goal needs it.
        self.guard.subscription(JointState, 'joint_states', self.on_joint_states,
                                LATEST_READER_QOS, raw=True)
        self.guard.subscription(DiagnosticStatus, 'controller/status', self.on_controller_status,
                                CONTROLLER_STATUS_QOS)
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
        self.publish_status('WARN', 'waiting for /joint_states', {})
        self.worker = threading.Thread(target=self.plan_loop, daemon=True)
        self.worker.start()
        self.get_logger().info(
            f'planner: motion={self.get_parameter("motion").value}, '
            f'limit_set={limit_set}, frame={self.get_parameter("frame_id").value}; '
            'waiting for /joint_states')

    # --- inputs (executor thread) ----------------------------------------------------------

    def on_joint_states(self, raw: bytes) -> None:
        """
        Keep the latest /joint_states as it came (serialized) with its arrival time.

        Nothing else per message: deserialising and mapping 100 messages a second to keep one
        cost more CPU than the rest of the idle planner. ``positions`` converts on demand; only
        while the planner is not ready is each message converted, to say ready on the first
        valid one.
        """
        self.states = (raw, now_ns(self.get_clock()))
        if self.state != READY and self.q is not None:
            self.set_state(READY)
        if not self.states_came.is_set():     # set already: the same (and no lock taken)
            self.states_came.set()

    def positions(self, raw: bytes) -> np.ndarray:
        """Return the joint positions [rad] of a serialized JointState; raise when malformed."""
        if self._converted is None or self._converted[0] is not raw:
            msg = deserialize_message(raw, JointState)
            try:
                q, _ = conversions.joint_state_from_msg(msg, self.arm.joint_names)
            except Mover6Error as err:
                raise Mover6Error(f'the latest /joint_states is malformed ({err}): '
                                  'the current pose is unknown') from err
            self._converted = (raw, q)
        return self._converted[1]

    @property
    def q(self) -> Optional[np.ndarray]:
        """Return the latest joint positions (6,) [rad], or None (none yet, or malformed)."""
        try:
            return None if self.states is None else self.positions(self.states[0])
        except Mover6Error:
            return None

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
        """Drop every goal received so far that waits or is being planned; send none again."""
        with self.lock:
            self.stopped_seq = self.goal_seq
            dropped = list(self.unconfirmed.values())
            self.unconfirmed.clear()
            for entry in dropped:
                if not entry.announced:       # said after 'planned' (planner_delivery)
                    entry.held = ('stopped before any controller named it', 'stopped')
            dropped = [entry for entry in dropped if entry.announced]
        response.success = True
        response.message = (f'goals up to {self.stopped_seq} dropped: none of them is planned '
                            "or sent from now on (the controller's ~/stop stops the arm)")
        self.get_logger().info(f'stop: {response.message}')
        for entry in dropped:
            self.refuse(entry.motion, 'stopped before any controller named it', 'stopped', {},
                        entry.goal)
        return response

    def submit(self, header: Header, motion: str, prepare: Callable[[], Callable]) -> None:
        """
        Give a goal its id, check its form, and queue it for the planning thread.

        ``prepare()`` checks the message (cheap: no kinematics) and returns its plan function
        ``f(q, settings)``; a malformed goal is refused here at once, even while another one is
        being planned.
        """
        with self.lock:
            self.goal_seq += 1
            seq = self.goal_seq
        stamp = f'{header.stamp.sec}.{header.stamp.nanosec:09d}'
        goal = {'goal_id': f'{stamp}-{seq}', 'goal_stamp': stamp, 'goal_seq': seq}
        try:
            profile = conversions.goal_profile_from_header(header)
            if profile:
                goal['profile'] = profile      # forwarded with the demand
            plan_fn = prepare()
        except (Mover6Error, ValueError) as err:
            self.refuse(motion, str(err), 'invalid_goal', {}, goal)
            raise                   # refused: the guard counts it too
        self.jobs.put((goal, motion, plan_fn, time.monotonic()))

    # --- status ----------------------------------------------------------------------------

    def set_state(self, state: PlannerState) -> None:
        """Say on the status that the planner is ready, or waiting for /joint_states."""
        with self.lock:
            if self.state == state:
                return
            self.state = state
        if state == READY:
            self.get_logger().info('planner ready: /joint_states received')
            self.publish_status('OK', 'ready: waiting for goals', {})
        else:
            self.publish_status('WARN', 'waiting for /joint_states', {})

    def refuse(self, motion: str, text: str, reason: str, details: dict, goal: dict) -> None:
        """Report a refused goal on /planner/status and in the log; publish no demands."""
        values = {'result': PlannerResult.REFUSED, 'motion': motion, 'reason': reason}
        for key in ('waypoint', 'position_error', 'orientation_error', 'fraction', 'shapes',
                    'depth'):
            if key in details:
                values[key] = details[key]
        closest = details.get('closest_pose')
        if closest is not None:
            T = np.asarray(closest)
            values['closest_pose_xyzabc'] = ' '.join(
                f'{v:.4f}' for v in list(T[:3, 3]) + list(matrix_to_euler_zyx(T[:3, :3])))
        self.get_logger().error(f'goal {goal["goal_id"]} refused ({reason}): {text}')
        self.publish_status('ERROR', f'goal refused ({reason}): {text}', values, goal)

    def publish_status(self, level: str, text: str, values: dict,
                       goal: Optional[dict] = None) -> None:
        """Publish /planner/status: ``state``, then the goal it is about (if any), then values."""
        merged = {'state': self.state}
        merged.update(goal or {})
        merged.update(values)
        with self.status_lock:
            self.status_pub.publish(conversions.make_status('planner', level, text, merged))

    def destroy_node(self) -> None:
        """End the planning thread (a goal being planned finishes first), then the node."""
        self.running = False
        self.jobs.put(None)
        self.states_came.set()
        if self.worker.is_alive() and self.worker is not threading.current_thread():
            self.worker.join(timeout=5.0)
        super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Run the planner node until Ctrl-C, SIGTERM or shutdown (one or more signals: exit 0)."""
    shutdown.run_node(PlannerNode, args)


if __name__ == '__main__':
    main()
