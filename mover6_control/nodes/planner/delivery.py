"""
The planner node's delivery of demands: sent when matched, again until a controller names them.

The graph can show a freshly started controller's reader before the planner's writer has matched
it, and a demand published then is lost (volatile durability); so a demand is published once the
known readers of /joint_demands are matched (or after ``match_timeout``), and sent again every
``RESEND_AFTER`` until the controller's status names its goal (taken, or refused: the goal's end),
at most ``RESENDS`` more times; then the goal fails (``not_acknowledged``).

The demand goes out before its duration is predicted (``control.planners.predicted_duration``,
the controller's own timing of the plan: at 1000 waypoints most of the planning time, and no
check: every refusal comes before the demand). The status then says 'planned' with that
duration; a controller's refusal or a ~/stop that comes meanwhile is held (``Unconfirmed.held``)
and said after 'planned', in the order the status always had.

``DemandDelivery`` is a part of ``planner_node.PlannerNode`` (its state is the node's, set in
``PlannerNode.__init__``); it is not used on its own.
"""

import dataclasses
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.control.planners import predicted_duration
from mover6_control.control.status import PlannerResult
from mover6_control.errors import Mover6Error
from mover6_control.nodes.messages import conversions, demand_messages
from mover6_control.nodes.planner.planning_thread import POLL
from mover6_control.planning.planner_core import JointPlan
import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import Float32MultiArray

# The controller's status is read with a deeper queue: each status may name a goal it took.
CONTROLLER_STATUS_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# [s] a demand no controller acknowledged (by goal id in its status) is sent again after this,
# at most RESENDS more times; then the goal fails (not_acknowledged). The controller waits for
# its first states at most controller_demands.DEMAND_STATE_WAIT (2 s) before it answers: less than
# RESEND_AFTER * (RESENDS + 1) = 6 s. The window also covers a controller that the graph did not
# show yet when the demand first went out (another reader of /joint_demands, a goal client,
# matched): on a loaded machine its discovery took more than 3 s (a fresh clone's suite).
RESEND_AFTER = 1.0
RESENDS = 5


@dataclasses.dataclass
class Unconfirmed:
    """A demand sent that no controller has named yet."""

    goal: dict
    motion: str
    msg: Float32MultiArray
    sent: float        # [s] monotonic time of the last send
    count: int         # times sent
    first: float       # [s] monotonic time of the first send
    announced: bool = False   # the status has said 'planned'
    held: Optional[tuple] = None   # (text, reason) of a refusal said once announced


class DemandDelivery:
    """The delivery of the planner's demands (module docstring)."""

    def on_controller_status(self, msg: DiagnosticStatus) -> None:
        """
        Note the controller's status: it names the goal it took, or refused and why.

        A refusal there is the goal's end: the planner's status says so (``controller_refused``
        with the controller's reason), in place of 'planned'.
        """
        values = conversions.status_values(msg)
        self.controller_values = values
        with self.lock:
            taken = self.unconfirmed.pop(values.get('goal_id') or None, None)
            refused = self.unconfirmed.pop(values.get('rejected_goal_id') or None, None)
            if refused is not None and not refused.announced:
                # Said by ``deliver`` after 'planned' (module docstring).
                refused.held = ('the controller refused the demand: '
                                + values.get('rejected', ''), 'controller_refused')
                refused = None
        if taken is not None:
            self.get_logger().info(f'goal {taken.goal["goal_id"]}: the controller took it '
                                   f'(motion {values.get("motion_id", "?")})')
        if refused is not None:
            self.refuse(refused.motion, 'the controller refused the demand: '
                        + values.get('rejected', ''), 'controller_refused', {}, refused.goal)

    def subscribers_matched(self) -> tuple[int, int]:
        """
        Return (matched, known): /joint_demands readers matched, and readers in the graph.

        A reader the graph shows but the publisher has not matched yet would miss a message
        published now (volatile durability); under load discovery can take a few seconds.
        """
        known = len(self.get_subscriptions_info_by_topic(self.demands_pub.topic_name))
        return self.demands_pub.get_subscription_count(), known

    def deliver(self, goal: dict, motion: str, plan: JointPlan, profile: str,
                q_start: np.ndarray) -> None:
        """
        Publish the plan once every known reader of /joint_demands is matched; say planned.

        The duration ``profile`` takes from ``q_start`` is predicted after the demand is out
        (module docstring).
        """
        since = time.monotonic()
        while True:
            matched, known = self.subscribers_matched()
            waited = time.monotonic() - since
            if matched >= max(known, 1) or waited >= self.get_parameter('match_timeout').value:
                break
            if self.stopped(goal) or not self.running:
                break
            time.sleep(POLL)
        if self.stopped(goal) or not self.running:
            self.refuse(motion, 'stopped before its demand was sent', 'stopped', {}, goal)
            return
        if matched == 0:
            self.refuse(motion, 'nobody subscribes to /joint_demands: is the controller running?',
                        'no_controller', {}, goal)
            return
        msg = demand_messages.make_demands(plan.q, goal['goal_id'], goal.get('profile', ''))
        now = time.monotonic()
        entry = Unconfirmed(goal, motion, msg, now, 1, now)
        with self.lock:
            self.unconfirmed[goal['goal_id']] = entry
        self.demands_pub.publish(msg)
        # One timing model: the controller's law times the waypoints from the same start.
        try:
            plan = dataclasses.replace(plan, predicted_duration=predicted_duration(
                profile, q_start, plan.q, self.arm.velocity_limits))
        except (Mover6Error, ValueError) as err:
            # Not a check (the controller times the demand and says if it refuses it): the
            # status keeps the planner's rough estimate.
            self.get_logger().warning(
                f'goal {goal["goal_id"]}: the duration was not predicted ({err}); the '
                f'estimate says {plan.predicted_duration:.2f} s')
        values = {'result': PlannerResult.PLANNED, 'motion': motion, 'waypoints': plan.n_waypoints,
                  'path_length': f'{plan.path_length:.6f}',
                  'predicted_duration': f'{plan.predicted_duration:.3f}',
                  'position_error': f'{plan.final_position_error:.3e}',
                  'orientation_error': f'{plan.final_orientation_error:.3e}'}
        text = (f'planned {motion} move: {plan.n_waypoints} waypoints, '
                f'{plan.path_length * 1e3:.1f} mm, about {plan.predicted_duration:.2f} s')
        self.get_logger().info(f'goal {goal["goal_id"]}: {text}')
        # The status first: a controller's refusal of the demand, or a stop, comes after it.
        self.publish_status('OK', text, values, goal)
        with self.lock:
            entry.announced = True
            held = entry.held
        if held is not None:
            self.refuse(motion, held[0], held[1], {}, goal)

    def resend_due(self) -> Optional[float]:
        """Return the time [s] until the next demand is due again (None: none waits)."""
        with self.lock:
            if not self.unconfirmed:
                return None
            due = min(u.sent for u in self.unconfirmed.values()) + RESEND_AFTER
        return max(due - time.monotonic(), POLL)

    def confirm_delivery(self) -> None:
        """
        Send a demand again while no controller has acknowledged its goal (up to RESENDS times).

        The graph can show a freshly started controller's reader before the planner's writer
        has matched it; a demand published then is lost (volatile durability). The controller
        names in its status the goal it took or refused (``on_controller_status``), and ignores
        a goal id it already had, so sending again is safe. After the last send the goal fails
        (``not_acknowledged``) on the status.
        """
        now = time.monotonic()
        resend, failed = [], []
        with self.lock:
            for goal_id, entry in list(self.unconfirmed.items()):
                if now - entry.sent < RESEND_AFTER:
                    continue
                if entry.count > RESENDS:
                    failed.append(self.unconfirmed.pop(goal_id))
                    continue
                entry.sent, entry.count = now, entry.count + 1
                resend.append(entry)
        for entry in resend:
            self.get_logger().info(f'goal {entry.goal["goal_id"]}: not acknowledged yet, '
                                   'sending the demand again')
            self.demands_pub.publish(entry.msg)
        for entry in failed:
            text = (f'no controller acknowledged the demand (sent {entry.count} times in '
                    f'{now - entry.first:.1f} s): is the controller running?')
            self.get_logger().error(f'goal {entry.goal["goal_id"]} failed: {text}')
            self.publish_status('ERROR', f'goal failed (not_acknowledged): {text}',
                                {'result': PlannerResult.FAILED, 'motion': entry.motion,
                                 'reason': 'not_acknowledged'}, entry.goal)
