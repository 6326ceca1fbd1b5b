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
"""

import dataclasses

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.collision.checker import CollisionChecker
from mover6_control.control.velocity_laws import predicted_duration
from mover6_control.errors import Mover6Error, UnreachableError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.rotations import matrix_to_euler_zyx
from mover6_control.nodes import conversions, params, shutdown
from mover6_control.parameters import PLANNER
from mover6_control.planning.planner_core import (PATH_MOTIONS, plan_path_goal, plan_pose_goal,
                                                  PlannerSettings, POSE_MOTIONS)
from mover6_control.planning.via_joint import plan_via_path_goal
import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

STATUS_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# [s] a demand no controller acknowledged (by goal id in its status) is sent again after this,
# at most RESENDS more times.
RESEND_AFTER = 1.0
RESENDS = 2


def settings_from_parameters(get):
    """
    Return the ``PlannerSettings`` of a parameter getter ``get(name)``; raise when invalid.

    The set-parameters check builds it from the values a set would leave in force, so a value
    the planner could not plan with (a tool size, keep-out boxes) is refused at the set.
    """
    return PlannerSettings(
        n_waypoints=get('n_waypoints'), max_step=get('max_step'),
        max_angle_step=get('max_angle_step'), peak_height=get('peak_height'),
        max_joint_step=get('max_joint_step'), max_condition=get('max_condition'),
        position_tolerance=get('position_tolerance'),
        orientation_tolerance=get('orientation_tolerance'),
        collision=params.collision_settings(get))


class PlannerNode(Node):
    """Plan pose and path goals into joint waypoints, refuse what cannot be reached."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the arm, start the topics."""
        super().__init__('planner', **kwargs)
        # Refuses invalid values, each and as the planner's settings, at start and later.
        params.declare(self, PLANNER, settings_from_parameters)
        limit_set = self.get_parameter('limit_set').value
        self.arm = mover6(limit_set)
        self.q = None
        self.q_time = None
        self.goal_seq = 0
        self.goal = {'goal_id': '', 'goal_stamp': '', 'goal_seq': 0}   # the latest goal
        self.pending = None      # a plan waiting for /joint_demands readers to be matched
        self.unconfirmed = None  # (goal_id, message, last sent, times sent): not yet acknowledged
        self.controller_values = {}
        self._checker = None     # the collision checker of the latest settings
        self.create_timer(0.02, self.publish_pending)
        self.demands_pub = self.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.status_pub = self.create_publisher(DiagnosticStatus, 'planner/status', STATUS_QOS)
        self.create_subscription(JointState, 'joint_states', self.on_joint_states, 10)
        self.create_subscription(DiagnosticStatus, 'controller/status', self.on_controller_status,
                                 STATUS_QOS)
        self.create_subscription(PoseStamped, 'pose_goal', self.on_pose_goal, 10)
        self.create_subscription(PoseArray, 'path_goal', self.on_path_goal, 10)
        for shape in POSE_MOTIONS:
            self.create_subscription(PoseStamped, f'pose_goal/{shape}',
                                     lambda msg, shape=shape: self.on_pose_goal(msg, shape), 10)
        for shape in PATH_MOTIONS:
            self.create_subscription(PoseArray, f'path_goal/{shape}',
                                     lambda msg, shape=shape: self.on_path_goal(msg, shape), 10)
        self.create_subscription(PoseArray, 'path_goal/joint', self.on_via_joint_goal, 10)
        self.publish_status('OK', 'waiting for goals', {'result': 'ready'})
        self.get_logger().info(
            f'planner ready: motion={self.get_parameter("motion").value}, '
            f'limit_set={limit_set}, frame={self.get_parameter("frame_id").value}')

    # --- inputs ----------------------------------------------------------------------------

    def on_joint_states(self, msg):
        """Keep the latest valid joint positions; drop malformed states with a warning."""
        try:
            q, _ = conversions.joint_state_from_msg(msg, self.arm.joint_names)
        except Mover6Error as err:
            self.get_logger().warn(f'dropped /joint_states: {err}', throttle_duration_sec=2.0)
            return
        self.q = q
        self.q_time = self.get_clock().now()

    def on_pose_goal(self, msg, motion=None):
        """Plan a pose goal with ``motion``, by default the shape of the ``motion`` parameter."""
        motion = motion or self.get_parameter('motion').value
        self.handle_goal(msg.header, motion, lambda q, settings: plan_pose_goal(
            self.arm, q, conversions.pose_stamped_to_matrix(msg, self.frame_id()), motion,
            settings, self.checker(settings)))

    def on_path_goal(self, msg, motion=None):
        """Plan a path goal (via poses then the goal) with ``motion`` (or ``path_motion``)."""
        motion = motion or self.get_parameter('path_motion').value

        def plan(q, settings):
            poses = conversions.pose_array_to_matrices(msg, self.frame_id())
            return plan_path_goal(self.arm, q, poses[:-1], poses[-1], motion, settings,
                                  self.checker(settings))
        self.handle_goal(msg.header, motion, plan)

    def on_via_joint_goal(self, msg):
        """Plan a joint move through one via pose (PoseArray [via, goal]): ``via_joint``."""
        def plan(q, settings):
            poses = conversions.pose_array_to_matrices(msg, self.frame_id())
            return plan_via_path_goal(self.arm, q, poses[:-1], poses[-1], settings)
        self.handle_goal(msg.header, 'joint', plan)

    # --- planning --------------------------------------------------------------------------

    def frame_id(self):
        """Return the frame goals must be given in."""
        return self.get_parameter('frame_id').value

    def settings(self):
        """Return the planner settings from the current parameters."""
        return settings_from_parameters(lambda n: self.get_parameter(n).value)

    def checker(self, settings):
        """Return the collision checker of ``settings`` (kept while they do not change)."""
        if not settings.collision.enabled:
            return None
        if self._checker is None or self._checker.settings != settings.collision:
            self._checker = CollisionChecker(self.arm, settings.collision)
        return self._checker

    def current_q(self):
        """Return the latest joint positions, or raise when there are none or they are old."""
        if self.q is None:
            raise Mover6Error('no /joint_states received yet: the current pose is unknown')
        age = (self.get_clock().now() - self.q_time).nanoseconds * 1e-9
        timeout = self.get_parameter('state_timeout').value
        if age > timeout:
            raise Mover6Error(f'/joint_states are {age:.2f} s old (limit {timeout:.2f} s): '
                              'the current pose is uncertain')
        return self.q.copy()

    def handle_goal(self, header, motion, plan_fn):
        """Plan, then publish the waypoints and OK, or nothing and ERROR with the reason."""
        self.goal_seq += 1
        stamp = f'{header.stamp.sec}.{header.stamp.nanosec:09d}'
        self.goal = {'goal_id': f'{stamp}-{self.goal_seq}', 'goal_stamp': stamp,
                     'goal_seq': self.goal_seq}
        try:
            profile = conversions.goal_profile_from_header(header)
            if profile:
                self.goal['profile'] = profile      # forwarded with the demand
            q_now = self.current_q()
            plan = plan_fn(q_now, self.settings())
            # One timing model: the controller's law times the waypoints from the same start.
            plan = dataclasses.replace(plan, predicted_duration=predicted_duration(
                profile or self.get_parameter('profile').value, q_now, plan.q,
                self.arm.velocity_limits))
        except UnreachableError as err:
            self.refuse(motion, str(err), err.reason, err.details)
            return
        except (Mover6Error, ValueError) as err:
            self.refuse(motion, str(err), 'invalid_goal', {})
            return
        self.pending = (dict(self.goal), motion, plan, self.get_clock().now())
        self.publish_pending()

    def subscribers_matched(self):
        """
        Return (matched, known): /joint_demands readers matched, and readers in the graph.

        A reader the graph shows but the publisher has not matched yet would miss a message
        published now (volatile durability); under load discovery can take a few seconds.
        """
        known = len(self.get_subscriptions_info_by_topic(self.demands_pub.topic_name))
        return self.demands_pub.get_subscription_count(), known

    def on_controller_status(self, msg):
        """Note the controller's status: it names the goal it took (or refused)."""
        self.controller_values = conversions.status_values(msg)

    def confirm_delivery(self):
        """
        Send a demand again while no controller has acknowledged its goal (up to RESENDS times).

        The graph can show a freshly started controller's reader before the planner's writer
        has matched it; a demand published then is lost (volatile durability). The controller
        names in its status the goal it took or refused, and ignores a goal id it already had,
        so sending again is safe.
        """
        if self.unconfirmed is None:
            return
        goal_id, msg, sent, count = self.unconfirmed
        v = self.controller_values
        if goal_id in (v.get('goal_id'), v.get('rejected_goal_id')):
            self.unconfirmed = None
            return
        now = self.get_clock().now()
        if (now - sent).nanoseconds * 1e-9 < RESEND_AFTER:
            return
        if count > RESENDS:
            self.unconfirmed = None
            self.get_logger().warning(f'goal {goal_id}: no controller acknowledged the demand')
            return
        self.get_logger().info(f'goal {goal_id}: not acknowledged yet, sending the demand again')
        self.demands_pub.publish(msg)
        self.unconfirmed = (goal_id, msg, now, count + 1)

    def publish_pending(self):
        """Publish the pending plan once every known reader of /joint_demands is matched."""
        self.confirm_delivery()
        if self.pending is None:
            return
        goal, motion, plan, since = self.pending
        matched, known = self.subscribers_matched()
        waited = (self.get_clock().now() - since).nanoseconds * 1e-9
        if matched < max(known, 1) and waited < self.get_parameter('match_timeout').value:
            return   # the timer calls again
        self.pending = None
        if matched == 0:
            self.refuse(motion, 'nobody subscribes to /joint_demands: is the controller running?',
                        'no_controller', {}, goal)
            return
        msg = conversions.make_demands(plan.q, goal['goal_id'], goal.get('profile', ''))
        self.demands_pub.publish(msg)
        self.unconfirmed = (goal['goal_id'], msg, self.get_clock().now(), 1)
        values = {'result': 'planned', 'motion': motion, 'waypoints': plan.n_waypoints,
                  'path_length': f'{plan.path_length:.6f}',
                  'predicted_duration': f'{plan.predicted_duration:.3f}',
                  'position_error': f'{plan.final_position_error:.3e}',
                  'orientation_error': f'{plan.final_orientation_error:.3e}'}
        text = (f'planned {motion} move: {plan.n_waypoints} waypoints, '
                f'{plan.path_length * 1e3:.1f} mm, about {plan.predicted_duration:.2f} s')
        self.get_logger().info(f'goal {goal["goal_id"]}: {text}')
        self.publish_status('OK', text, values, goal)

    def refuse(self, motion, text, reason, details, goal=None):
        """Report a refused goal on /planner/status and in the log; publish no demands."""
        values = {'result': 'refused', 'motion': motion, 'reason': reason}
        for key in ('waypoint', 'position_error', 'orientation_error', 'fraction', 'shapes',
                    'depth'):
            if key in details:
                values[key] = details[key]
        closest = details.get('closest_pose')
        if closest is not None:
            T = np.asarray(closest)
            values['closest_pose_xyzabc'] = ' '.join(
                f'{v:.4f}' for v in list(T[:3, 3]) + list(matrix_to_euler_zyx(T[:3, :3])))
        goal = goal or self.goal
        self.get_logger().error(f'goal {goal["goal_id"]} refused ({reason}): {text}')
        self.publish_status('ERROR', f'goal refused ({reason}): {text}', values, goal)

    def publish_status(self, level, text, values, goal=None):
        """Publish /planner/status with the id of the goal it is about added to the values."""
        values = dict(values, **(goal or self.goal))
        self.status_pub.publish(conversions.make_status('planner', level, text, values))


def main(args=None):
    """Run the planner node until Ctrl-C, SIGTERM or shutdown (one or more signals: exit 0)."""
    shutdown.run_node(PlannerNode, args)


if __name__ == '__main__':
    main()
