"""
The web console: see the arm and drive it from a browser (viser), one page for every tab.

``ros2 run mover6_control console [--host 127.0.0.1] [--port 8080]`` serves the page on
http://127.0.0.1:8080 (the client is viser's, served from the installed package: no network
beyond the machine). Serving on another address needs ``--host`` and prints a warning: the page
can move the arm. Every tab shows the same scene and panels (viser shares them).

The node reads /joint_states (the arm from config/mover6.urdf follows them), /joint_demands (the
planned tool path, by the package's forward kinematics), /planner/status, /controller/status
and /diagnostics (a driver's joints: flags, referenced, the e-stop); it asks the planner for its
parameters (the settings of "Plan" and the collision scene: table, margin, keep-out boxes, the
tool) every ``SETTINGS_PERIOD``. It sends:

- "Plan": nothing. The goal is planned here, by the planner's own core with the planner's
  settings from the measured joints (``page_logic.Preview``): the path, or the refusal with its
  reason and the closest reachable pose as a ghost arm. The planner has no plan-only mode;
- "Go": the goal to the planner, on the topic of its shape (``/pose_goal/<shape>``,
  ``/path_goal/<shape>`` with via poses; the profile in the frame id); the planner's answer
  about that goal (by its stamp) is shown, its /joint_demands drawn;
- "Stop": the controller's ``~/stop`` and the planner's ``~/stop`` (queued goals dropped);
- jogging: ``controller/delta_joint_cmds`` (JointJog) and ``controller/delta_twist_cmds``
  (TwistStamped) at ``SCENE_RATE`` while a command is held, one zero command after it;
- a driver's ``~/reset``, ``~/enable``, ``~/reference``, ``~/disable`` by its buttons.

Every callback, ROS and page alike, runs through the node's ``CallbackGuard``: a page input
that raises is one refused input, shown on the page and counted on ``~/guard``.
"""

import argparse
import ipaddress
from pathlib import Path
import sys
import threading
import time
from typing import Optional

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseArray, PoseStamped, TwistStamped
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk_batch
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.console.collision_scene import CollisionScene
from mover6_control.nodes.console.goal_panel import GoalPanel, GoalRequest
from mover6_control.nodes.console.jog_panel import JogPanel
from mover6_control.nodes.console.page_logic import GoalConvention, Preview
from mover6_control.nodes.console.state_view import StateView
from mover6_control.nodes.console.status_panel import Snapshot, Status, StatusPanel
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.messages.demand_messages import demands_from_msg
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_configs import planner_settings_from_parameters
from mover6_control.nodes.runtime.qos import LATEST_READER_QOS, STATUS_READER_QOS
from mover6_control.parameters import PLANNER
from mover6_control.resources import CONFIG_DIR
import numpy as np
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
from std_srvs.srv import Trigger
import viser

SCENE_RATE = 20.0          # [Hz] the arm, the tool and the jog commands
STATUS_PERIOD = 0.5        # [s] the status panel and the graph check
SETTINGS_PERIOD = 2.0      # [s] the planner's parameters asked again
DEFAULT_PORT = 8080


class ConsoleNode(Node):
    """The console's node: its topics, services and the page's parts; see the module doc."""

    def __init__(self, host: str = '127.0.0.1', port: int = DEFAULT_PORT,
                 planner: str = 'planner', controller: str = 'controller',
                 driver: str = 'driver', **kwargs):
        """Start the page's server on ``host``:``port``, build the page, start the topics."""
        super().__init__('console', **kwargs)
        self.guard = CallbackGuard(self)
        wrap = self.guard.wrap
        self.lock = threading.Lock()     # the latest statuses and the goal sent
        self.arm = mover6(PLANNER['limit_set'].default)
        self.settings_values = {name: spec.default for name, spec in PLANNER.items()}
        self.settings = planner_settings_from_parameters(self.settings_values.get)
        self.q = None
        self.statuses = {}
        self.driver_joints = {}
        self.sent = None                 # (goal stamp text, GoalRequest) of the latest Go
        self.answered = None             # the planner's status about it, once shown
        self.missing = ()
        self.last_action = ''
        self.names = {'planner': planner, 'controller': controller, 'driver': driver}
        self.server = viser.ViserServer(host=host, port=port, label='Mover6 console',
                                        verbose=False)
        self.server.scene.set_up_direction('+z')
        self.server.initial_camera.position = (0.85, -0.75, 0.65)
        self.server.initial_camera.look_at = (0.2, 0.0, 0.25)
        self.scene = CollisionScene(self.server, self.arm)
        self.scene.show(self.settings.collision)
        self.view = StateView(self.server, Path(CONFIG_DIR) / 'mover6.urdf',
                              self.arm.joint_names, self.scene.geometry)
        self.view.show_joints(np.zeros(self.arm.n_joints))
        self.scene.follow(np.zeros(self.arm.n_joints))
        self.convention = GoalConvention(self.arm)
        self.preview = Preview(self.arm)
        self.goal = GoalPanel(self.server, self.convention, self.on_plan, self.on_go,
                              self.on_stop, self.page_wrap)
        self.jog = JogPanel(self.server, self.arm.joint_names, self.page_wrap, time.monotonic)
        self.status = StatusPanel(self.server, self.on_driver, self.page_wrap)
        self.publishers_by_topic = {}
        self.joint_jog_pub = self.create_publisher(JointJog, f'{controller}/delta_joint_cmds',
                                                   10)
        self.twist_pub = self.create_publisher(TwistStamped, f'{controller}/delta_twist_cmds',
                                               10)
        self.clients_by_name = {}
        self.params_client = self.create_client(GetParameters, f'{planner}/get_parameters')
        self.guard.subscription(JointState, 'joint_states', self.on_joint_states,
                                LATEST_READER_QOS)
        self.guard.subscription(Float32MultiArray, 'joint_demands', self.on_demands, 10)
        self.guard.subscription(DiagnosticStatus, f'{planner}/status',
                                lambda msg: self.on_status('planner', msg), STATUS_READER_QOS)
        self.guard.subscription(DiagnosticStatus, f'{controller}/status',
                                lambda msg: self.on_status('controller', msg),
                                STATUS_READER_QOS)
        self.guard.subscription(DiagnosticArray, 'diagnostics', self.on_diagnostics, 10)
        self.guard.timer(1.0 / SCENE_RATE, self.on_scene_tick)
        self.guard.timer(STATUS_PERIOD, self.on_status_tick)
        self.guard.timer(SETTINGS_PERIOD, self.ask_settings)
        self.ask_settings()
        self.get_logger().info(f'console on http://{host}:{port}')

    def page_wrap(self, source: str, callback):
        """Guard a page callback: a refusal is counted, logged and said on the page."""
        def said(code, reason, *_):
            self.goal.say(f'refused ({code}): {reason}')
        return self.guard.wrap(source, callback, said)

    # --- ROS inputs ------------------------------------------------------------------------

    def on_joint_states(self, msg: JointState) -> None:
        """Keep the measured joints (the scene tick shows them)."""
        q, _ = conversions.joint_state_from_msg(msg, self.arm.joint_names)
        self.q = q

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Draw the tool path of the planner's (or anyone's) joint demands."""
        Q = demands_from_msg(msg, self.arm.n_joints)
        self.view.show_path('demand', fk_batch(self.arm, Q)[:, :3, 3])
        self.view.show_path('preview', None)

    def on_status(self, who: str, msg: DiagnosticStatus) -> None:
        """Keep a node's status; show the planner's answer about the goal sent by Go."""
        status = Status(conversions.status_level_name(msg), msg.message,
                        conversions.status_values(msg))
        with self.lock:
            self.statuses[who] = status
            sent = self.sent
        if who == 'planner' and sent is not None:
            self.show_planner_answer(status, *sent)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Keep a driver's bus and joint statuses (names 'driver' and 'driver: <joint>')."""
        for entry in msg.status:
            values = conversions.status_values(entry)
            status = Status(conversions.status_level_name(entry), entry.message, values)
            if entry.name == 'driver':
                with self.lock:
                    self.statuses['driver'] = status
            elif entry.name.startswith('driver: '):
                joint = entry.name[len('driver: '):]
                values = dict(values, name=joint)
                with self.lock:
                    self.driver_joints[joint] = Status(status.level, status.message, values)

    # --- timers ----------------------------------------------------------------------------

    def on_scene_tick(self) -> None:
        """Move the arm and the tool to the latest joints; send the jog commands held."""
        q = self.q
        if q is not None and (self.view.q is None or np.any(q != self.view.q)):
            self.view.show_joints(q)
            self.scene.follow(q)
        joints, twist, frame = self.jog.due(time.monotonic())
        stamp = self.get_clock().now().to_msg()
        if joints is not None:
            self.joint_jog_pub.publish(conversions.make_joint_jog(self.arm.joint_names, joints,
                                                                  stamp))
        if twist is not None:
            msg = TwistStamped()
            msg.header.stamp = stamp
            msg.header.frame_id = frame
            msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = map(float, twist[:3])
            msg.twist.angular.x, msg.twist.angular.y, msg.twist.angular.z = map(float,
                                                                                twist[3:])
            self.twist_pub.publish(msg)

    def on_status_tick(self) -> None:
        """Say what the graph lacks; show the statuses."""
        missing = []
        if self.count_publishers('joint_states') == 0:
            missing.append('/joint_states: no simulator or driver publishes them')
        for who in ('controller', 'planner'):
            if self.count_publishers(f'{self.names[who]}/status') == 0:
                missing.append(f'the {who} ({self.names[who]}/status has no publisher)')
        with self.lock:
            snapshot = Snapshot(
                controller=self.statuses.get('controller'), planner=self.statuses.get('planner'),
                driver=self.statuses.get('driver'),
                joints=tuple(self.driver_joints[k] for k in sorted(self.driver_joints)),
                missing=tuple(missing), last_action=self.last_action)
        self.status.show(snapshot)

    def ask_settings(self) -> None:
        """Ask the planner for its parameters: the settings of Plan and the collision scene."""
        if not self.params_client.service_is_ready():
            return
        request = GetParameters.Request(names=list(PLANNER))
        future = self.params_client.call_async(request)
        future.add_done_callback(self.guard.wrap('planner parameters', self.on_settings))

    def on_settings(self, future) -> None:
        """Take the planner's parameters (those it gave) as the page's settings."""
        response = future.result()
        if response is None:
            return
        values = dict(self.settings_values)
        for name, value in zip(PLANNER, response.values):
            values[name] = parameter_value_to_python(value)
        settings = planner_settings_from_parameters(values.get)
        if values['limit_set'] != self.settings_values['limit_set']:
            self.arm = mover6(values['limit_set'])
            self.preview = Preview(self.arm)
        self.settings_values, self.settings = values, settings
        self.scene.show(settings.collision)

    # --- the page's actions (viser's threads) -------------------------------------------------

    def on_plan(self, request: GoalRequest) -> None:
        """Plan here, move nothing: show the path, or the refusal and the closest pose."""
        q = self.q
        if q is None:
            raise InvalidInputError('no /joint_states: the start pose is unknown')
        answer = self.preview.plan(q, request.shape, request.T, request.vias, self.settings)
        self.view.show_path('preview', answer.path if answer.planned else None)
        self.view.show_ghost(answer.closest_q)
        text = f'Plan: {answer.text}'
        if not answer.planned:
            text += f' (ghost: {answer.closest_text})' if answer.closest_q is not None else ''
        self.goal.say(text)

    def on_go(self, request: GoalRequest) -> None:
        """Send the goal to the planner on its shape's topic; its answer follows by stamp."""
        route = request.route
        msg = PoseStamped() if route.kind == 'pose' else PoseArray()
        stamp = self.get_clock().now().to_msg()
        msg.header.stamp = stamp
        frame = str(self.settings_values.get('frame_id', 'base_link'))
        msg.header.frame_id = frame + (f' profile {request.profile}' if request.profile else '')
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
        self.goal.say(f'Go: sent on /{route.topic}; waiting for the planner')

    def show_planner_answer(self, status: Status, goal_stamp: str,
                            request: GoalRequest) -> None:
        """Show the planner's answer about the goal sent (refusal: reason, ghost)."""
        v = status.values
        if v.get('goal_stamp') != goal_stamp or v.get('result') in (None, 'waiting_for_states'):
            return
        if v['result'] == 'refused':
            closest = v.get('closest_pose_xyzabc')
            T = (pose_from_xyzabc(*[float(x) for x in closest.split()])
                 if closest else None)
            q = self.q if self.q is not None else np.zeros(self.arm.n_joints)
            answer = self.preview.refusal(q, request.T, status.message, v.get('reason', ''), T)
            self.view.show_ghost(answer.closest_q)
            ghost = f' (ghost: {answer.closest_text})' if answer.closest_q is not None else ''
            self.goal.say(f'Go: the planner refused the goal ({v.get("reason", "")}): '
                          f'{status.message}{ghost}')
        else:
            self.goal.say(f'Go: the planner says {v["result"]}: {status.message}')

    def on_stop(self) -> None:
        """Stop the arm (the controller's ~/stop) and drop queued goals (the planner's)."""
        said = [self.call(f'{self.names[who]}/stop') for who in ('controller', 'planner')]
        self.goal.say('Stop: ' + '; '.join(said))

    def on_driver(self, kind: str) -> None:
        """Call the driver's service ``kind`` (reset, enable, reference, disable)."""
        said = self.call(f'{self.names["driver"]}/{kind}')
        with self.lock:
            self.last_action = f'driver {kind}: {said}'

    def call(self, name: str) -> str:
        """Call the Trigger service ``name``; return what was done (the answer comes later)."""
        client = self.clients_by_name.get(name)
        if client is None:
            client = self.clients_by_name[name] = self.create_client(Trigger, name)
        if not client.service_is_ready():
            return f'/{name} is not there'
        future = client.call_async(Trigger.Request())
        future.add_done_callback(self.guard.wrap(name, lambda f, name=name: self.on_answer(
            name, f)))
        return f'/{name} called'

    def on_answer(self, name: str, future) -> None:
        """Show a service's answer."""
        response = future.result()
        with self.lock:
            self.last_action = (f'/{name}: {"done" if response.success else "refused"}: '
                                f'{response.message}')

    def publisher(self, msg_type: type, topic: str):
        """Return the publisher of ``topic`` (made once)."""
        pub = self.publishers_by_topic.get(topic)
        if pub is None:
            pub = self.publishers_by_topic[topic] = self.create_publisher(msg_type, topic, 10)
        return pub

    def destroy_node(self) -> None:
        """Stop the page's server, then the node."""
        self.server.stop()
        super().destroy_node()


def is_loopback(host: str) -> bool:
    """Return True when ``host`` is a loopback address (or 'localhost')."""
    if host == 'localhost':
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def parse_args(argv: list[str]) -> argparse.Namespace:
    """Return the console's options (ROS arguments left out)."""
    parser = argparse.ArgumentParser(
        prog='console', description='Mover6 web console: see the arm and drive it from a '
        'browser (http://HOST:PORT).')
    parser.add_argument('--host', default='127.0.0.1',
                        help='address to serve on (default 127.0.0.1; another one prints a '
                        'warning: the page can move the arm)')
    parser.add_argument('--port', type=int, default=DEFAULT_PORT, help='port (default 8080)')
    return parser.parse_args(argv)


def main(args: Optional[list[str]] = None) -> None:
    """Serve the console until Ctrl-C or SIGTERM."""
    argv = sys.argv if args is None else args
    options = parse_args(remove_ros_args(argv)[1:])
    if not is_loopback(options.host):
        print(f'WARNING: the console serves on {options.host}:{options.port}, not only this '
              'machine: anyone who reaches it can move the arm.', file=sys.stderr, flush=True)
    shutdown.run_node(lambda: ConsoleNode(options.host, options.port), argv)


if __name__ == '__main__':
    main()
