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
from typing import Callable, Optional

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from mover6_control.kinematics.forward import fk_batch
from mover6_control.nodes.console.collision_scene import CollisionScene
from mover6_control.nodes.console.goal_actions import GoalActions
from mover6_control.nodes.console.goal_panel import GoalPanel
from mover6_control.nodes.console.jog_panel import JogPanel
from mover6_control.nodes.console.page_logic import GoalConvention
from mover6_control.nodes.console.planner_settings import PlannerSettingsFollower
from mover6_control.nodes.console.state_view import StateView
from mover6_control.nodes.console.status_panel import PanelState, ShownStatus, StatusPanel
from mover6_control.nodes.driver.report_publisher import BUS_STATUS
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.messages.demand_messages import demands_from_msg
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.qos import LATEST_READER_QOS, STATUS_READER_QOS
from mover6_control.resources import CONFIG_DIR
import numpy as np
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
import viser

SCENE_RATE = 20.0          # [Hz] the arm, the tool and the jog commands
PANEL_PERIOD = 0.5         # [s] the status panel and the graph check
DEFAULT_PORT = 8080


class ConsoleNode(Node):
    """The console's node: its topics and the page's parts; see the module doc."""

    def __init__(self, host: str = '127.0.0.1', port: int = DEFAULT_PORT,
                 planner: str = 'planner', controller: str = 'controller',
                 driver: str = 'driver', **kwargs):
        """Start the page's server on ``host``:``port``, build the page, start the topics."""
        super().__init__('console', **kwargs)
        self.guard = CallbackGuard(self)
        self.lock = threading.Lock()     # the statuses
        self.q = None
        self.statuses = {}
        self.driver_joints = {}
        self.names = {'planner': planner, 'controller': controller, 'driver': driver}
        self.server = viser.ViserServer(host=host, port=port, label='Mover6 console',
                                        verbose=False)
        self.server.scene.set_up_direction('+z')
        self.server.initial_camera.position = (0.85, -0.75, 0.65)
        self.server.initial_camera.look_at = (0.2, 0.0, 0.25)
        self.settings = PlannerSettingsFollower(
            self, self.guard, planner, lambda s: self.scene.show(s.settings.collision))
        arm = self.settings.arm
        self.scene = CollisionScene(self.server, arm)
        self.scene.show(self.settings.settings.collision)
        self.view = StateView(self.server, Path(CONFIG_DIR) / 'mover6.urdf', arm.joint_names,
                              self.scene.geometry)
        self.view.show_joints(np.zeros(arm.n_joints))
        self.scene.follow(np.zeros(arm.n_joints))
        self.actions = GoalActions(self, self.guard, self.view, self.settings, self.names,
                                   lambda: self.q, lambda text: self.goal.say(text))
        self.goal = GoalPanel(self.server, GoalConvention(arm), self.actions.plan,
                              self.actions.go, self.actions.stop, self.page_wrap)
        self.jog = JogPanel(self.server, arm.joint_names, self.page_wrap, time.monotonic)
        self.status = StatusPanel(self.server, self.actions.driver, self.page_wrap)
        self.joint_jog_pub = self.create_publisher(JointJog, f'{controller}/delta_joint_cmds',
                                                   10)
        self.twist_pub = self.create_publisher(TwistStamped, f'{controller}/delta_twist_cmds',
                                               10)
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
        self.guard.timer(PANEL_PERIOD, self.on_panel_tick)
        self.settings.ask()
        self.get_logger().info(f'console on http://{host}:{port}')

    def page_wrap(self, source: str, callback: Callable) -> Callable:
        """Guard a page callback: a refusal is counted, logged and said on the page."""
        def said(code, reason, *_):
            self.goal.say(f'refused ({code}): {reason}')
        return self.guard.wrap(source, callback, said)

    # --- ROS inputs ------------------------------------------------------------------------

    def on_joint_states(self, msg: JointState) -> None:
        """Keep the measured joints (the scene tick shows them)."""
        q, _ = conversions.joint_state_from_msg(msg, self.settings.arm.joint_names)
        self.q = q

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Draw the tool path of the planner's (or anyone's) joint demands."""
        arm = self.settings.arm
        Q = demands_from_msg(msg, arm.n_joints)
        self.view.show_path('demand', fk_batch(arm, Q)[:, :3, 3])
        self.view.show_path('preview', None)

    def on_status(self, who: str, msg: DiagnosticStatus) -> None:
        """Keep a node's status; the planner's may answer the goal sent by Go."""
        status = ShownStatus(conversions.status_level_name(msg), msg.message,
                             conversions.status_values(msg))
        with self.lock:
            self.statuses[who] = status
        if who == 'planner':
            self.actions.on_planner_status(status)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Keep a driver's bus and joint statuses ('driver: bus' and 'driver: <joint>')."""
        for entry in msg.status:
            values = conversions.status_values(entry)
            level = conversions.status_level_name(entry)
            if entry.name == BUS_STATUS:
                with self.lock:
                    self.statuses['driver'] = ShownStatus(level, entry.message, values)
            elif entry.name.startswith('driver: '):
                joint = entry.name[len('driver: '):]
                with self.lock:
                    self.driver_joints[joint] = ShownStatus(level, entry.message,
                                                            dict(values, name=joint))

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
            self.joint_jog_pub.publish(conversions.make_joint_jog(
                self.settings.arm.joint_names, joints, stamp))
        if twist is not None:
            msg = TwistStamped()
            msg.header.stamp = stamp
            msg.header.frame_id = frame
            linear, angular = msg.twist.linear, msg.twist.angular
            linear.x, linear.y, linear.z = (float(v) for v in twist[:3])
            angular.x, angular.y, angular.z = (float(v) for v in twist[3:])
            self.twist_pub.publish(msg)

    def on_panel_tick(self) -> None:
        """Say what the graph lacks; show the statuses."""
        missing = []
        if self.count_publishers('joint_states') == 0:
            missing.append('/joint_states: no simulator or driver publishes them')
        for who in ('controller', 'planner'):
            if self.count_publishers(f'{self.names[who]}/status') == 0:
                missing.append(f'the {who} ({self.names[who]}/status has no publisher)')
        with self.lock:
            state = PanelState(
                controller=self.statuses.get('controller'), planner=self.statuses.get('planner'),
                driver=self.statuses.get('driver'),
                joints=tuple(self.driver_joints[k] for k in sorted(self.driver_joints)),
                missing=tuple(missing), last_action=self.actions.last_action)
        self.status.show(state)

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
