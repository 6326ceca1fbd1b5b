"""
What the console's buttons do: Plan, Go, Stop and the driver's services.

Plan is made here and moves nothing, Go goes to the planner, whose answer about the goal sent is
shown on the page; Stop and the driver's buttons call Trigger services.
"""

import threading
from typing import Callable

from geometry_msgs.msg import PoseArray, PoseStamped
from mover6_control.control.status import PlannerResult
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.console.goal_panel import GoalRequest
from mover6_control.nodes.console.planner_settings import PlannerSettingsFollower
from mover6_control.nodes.console.state_view import StateView
from mover6_control.nodes.console.status_panel import ShownStatus
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
import numpy as np
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.task import Future
from std_srvs.srv import Trigger


class GoalActions:
    """Plan, Go, Stop and the driver's buttons, for ``node``; ``say(text)`` answers the page."""

    def __init__(self, node: Node, guard: CallbackGuard, view: StateView,
                 settings: PlannerSettingsFollower, names: dict, joints: Callable,
                 say: Callable):
        """``names``: the node names (planner, controller, driver); ``joints()``: latest q."""
        self.node = node
        self.guard = guard
        self.view = view
        self.settings = settings
        self.names = names
        self.joints = joints
        self.say = say
        self.lock = threading.Lock()
        self.sent = None                 # (goal stamp text, GoalRequest) of the latest Go
        self.last_action = ''
        self.publishers = {}
        self.clients = {}

    def plan(self, request: GoalRequest) -> None:
        """Plan here, move nothing: show the path, or the refusal and the closest pose."""
        q = self.joints()
        if q is None:
            raise InvalidInputError('no /joint_states: the start pose is unknown')
        answer = self.settings.preview.plan(q, request.shape, request.T, request.vias,
                                            self.settings.settings)
        self.view.show_path('preview', answer.path if answer.planned else None)
        self.view.show_ghost(answer.closest_q)
        ghost = f' (ghost: {answer.closest_text})' if answer.closest_q is not None else ''
        self.say(f'Plan: {answer.text}{ghost}')

    def go(self, request: GoalRequest) -> None:
        """Send the goal to the planner on its shape's topic; its answer follows by stamp."""
        route = request.route
        msg = PoseStamped() if route.kind == 'pose' else PoseArray()
        stamp = self.node.get_clock().now().to_msg()
        msg.header.stamp = stamp
        msg.header.frame_id = self.settings.frame_id + (f' profile {request.profile}'
                                                        if request.profile else '')
        if route.kind == 'pose':
            msg.pose = conversions.matrix_to_pose(request.T)
        else:
            msg.poses = [conversions.matrix_to_pose(T) for T in request.vias + (request.T,)]
        pub = self.publisher(type(msg), route.topic)
        if pub.get_subscription_count() == 0:
            raise InvalidInputError(f'nobody reads /{route.topic}: is the planner running?')
        goal_stamp = f'{stamp.sec}.{stamp.nanosec:09d}'
        with self.lock:
            self.sent = (goal_stamp, request)
            self.last_action = f'Go: goal {goal_stamp} sent on /{route.topic}'
        self.view.show_ghost(None)
        pub.publish(msg)
        self.say(f'Go: sent on /{route.topic}; waiting for the planner')

    def on_planner_status(self, status: ShownStatus) -> None:
        """Show the planner's answer about the goal sent (a refusal: reason, ghost arm)."""
        with self.lock:
            sent = self.sent
        v = status.values
        if sent is None or v.get('goal_stamp') != sent[0] or v.get('result') in (
                None, PlannerResult.WAITING_FOR_STATES):
            return
        if v['result'] != PlannerResult.REFUSED:
            self.say(f'Go: the planner says {v["result"]}: {status.message}')
            return
        closest = v.get('closest_pose_xyzabc')      # base-frame ZYX angles
        T = pose_from_xyzabc(*[float(x) for x in closest.split()]) if closest else None
        q = self.joints()
        q = np.zeros(self.settings.arm.n_joints) if q is None else q
        answer = self.settings.preview.refusal(q, sent[1].T, status.message,
                                               v.get('reason', ''), T)
        self.view.show_ghost(answer.closest_q)
        ghost = f' (ghost: {answer.closest_text})' if answer.closest_q is not None else ''
        self.say(f'Go: the planner refused the goal ({v.get("reason", "")}): '
                 f'{status.message}{ghost}')

    def stop(self) -> None:
        """Stop the arm (the controller's ~/stop) and drop queued goals (the planner's)."""
        said = [self.call(f'{self.names[who]}/stop') for who in ('controller', 'planner')]
        self.say('Stop: ' + '; '.join(said))

    def driver(self, kind: str) -> None:
        """Call the driver's service ``kind`` (reset, enable, reference, disable)."""
        said = self.call(f'{self.names["driver"]}/{kind}')
        with self.lock:
            self.last_action = f'driver {kind}: {said}'

    def call(self, name: str) -> str:
        """Call the Trigger service ``name``; return what was done (the answer comes later)."""
        client = self.clients.get(name)
        if client is None:
            client = self.clients[name] = self.node.create_client(Trigger, name)
        if not client.service_is_ready():
            return f'/{name} is not there'
        future = client.call_async(Trigger.Request())
        future.add_done_callback(self.guard.wrap(name, lambda f, name=name: self.on_answer(
            name, f)))
        return f'/{name} called'

    def on_answer(self, name: str, future: Future) -> None:
        """Keep a service's answer (the status panel shows it)."""
        response = future.result()
        with self.lock:
            self.last_action = (f'/{name}: {"done" if response.success else "refused"}: '
                                f'{response.message}')

    def publisher(self, msg_type: type, topic: str) -> Publisher:
        """Return the publisher of ``topic`` (made once)."""
        pub = self.publishers.get(topic)
        if pub is None:
            pub = self.publishers[topic] = self.node.create_publisher(msg_type, topic, 10)
        return pub
