"""
The sim_bridge node: the MuJoCo arm on ROS 2, standing in for the Mover6 and its driver.

Subscribes /JointJog (control_msgs/JointJog: ``velocities`` by joint name; ``displacements``,
``duration`` and the stamp are ignored, as the vendor driver ignores them) and ~/reset_to
(sensor_msgs/JointState: reset to the named ``position`` values, unnamed joints to ``initial_q``).
Publishes /joint_states (names joint1..joint6 and the URDF's joints outside the arm's chain, the
gripper, which the simulated arm has not fitted: at 0, closed; position, velocity, effort, stamped)
at ``publish_rate``, at ``rest_publish_rate`` while the arm rests (no command moves it and every
joint is still, as the real arm's driver publishes at 10 to 20 Hz; the first step of a command that
moves it publishes at ``publish_rate`` again), and, with ``publish_clock``, /clock after every
physics step. ~/status (diagnostic_msgs/DiagnosticStatus, transient local), once a second: sim
time, the real-time factor measured since the last report, the /joint_states rate in force, whether
the arm rests, pacing overruns and rejected /JointJog messages. Services: ~/reset
(std_srvs/Trigger, to ``initial_q``), ~/pause (std_srvs/SetBool), ~/step (std_srvs/Trigger: one
control period while paused: one /joint_states period, or one 50 ms driver cycle in vendor mode).

Contacts: ~/contacts (diagnostic_msgs/DiagnosticStatus, transient local) reports what the
simulator's collision detection found on the arm's collision geometry (the checker's shapes):
OK with ``contact_steps`` 0 while nothing has touched since the last reset, WARN naming the
first contact (time, shapes, depth) and the shapes touching now once anything has. Sent at start,
on a reset and whenever ``contact_steps`` or the shapes touching change (at most once per
/joint_states period).

Physics runs in its own thread, paced against the monotonic wall clock at
``real_time_factor`` (0 = as fast as it can); callbacks and the physics thread share the
``Simulator`` under a lock. In 'vendor_driver' mode /joint_states come at the driver's own rate
(one per 50 ms cycle) and ``publish_rate`` is not used. Stamps are sim time with
``publish_clock`` (the bridge drives the clock), the node's clock otherwise. Parameters are
read at start; ``real_time_factor``, ``publish_rate`` and ``rest_publish_rate`` also apply live
when set (``ros2 param set``), the others are read-only.

The node is built from parts, each given what it needs in its constructor: the ``Simulator``;
the ``PhysicsThread`` (``sim_bridge/bridge_physics.py``: pacing, stepping, publishing through
its ``BridgeOutputs``, the node's publishers); ``SimControls`` (``sim_bridge/bridge_controls.py``,
no ROS: reset, pause and step on the physics thread); ``SimJogIntake`` (here: /JointJog into the
physics thread, refusals counted in the ``Rejections`` the physics thread reports). The node's
callbacks take the requests apart and call them.
"""

import os
import time
from typing import Any, Callable, Optional
import xml.etree.ElementTree as ET

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, LIMIT_SETS, load_urdf, mover6
from mover6_control.nodes.messages import cdr, conversions
from mover6_control.nodes.runtime import params, shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.qos import STATUS_QOS, STREAM_READER_QOS
from mover6_control.parameters import SIM_BRIDGE
from mover6_control.resources import CONFIG_DIR
import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from sim_bridge.bridge_controls import SimControls
from sim_bridge.bridge_physics import BridgeOutputs, Pacing, PhysicsThread, Rejections
from sim_bridge.model import ModelOptions
from sim_bridge.simulator import SimConfig, Simulator
from std_srvs.srv import SetBool, Trigger

MAX_PUBLISH_RATE = 500.0


def sim_config_from_parameters(get: Callable[[str], object]) -> SimConfig:
    """Return the ``SimConfig`` of a parameter getter ``get(name)``; raise when invalid."""
    return SimConfig(mode=get('mode'), command_timeout=float(get('command_timeout')),
                     speed_override=float(get('speed_override')),
                     model=ModelOptions(physics_dt=float(get('physics_dt')),
                                        kv=float(get('kv')), damping=float(get('damping'))))


def make_arm(limit_set: str, urdf_path: str) -> ArmModel:
    """Return the arm: the shipped Mover6 with ``limit_set``, or a given URDF."""
    if limit_set not in LIMIT_SETS:
        raise InvalidInputError(f'limit_set must be one of {LIMIT_SETS}, got {limit_set!r}')
    if urdf_path:
        return load_urdf(urdf_path)
    return mover6(limit_set)


def unfitted_joints(arm: ArmModel, urdf_path: str) -> dict:
    """
    Return {name: position} of the URDF's moving joints outside ``arm``'s chain (the gripper).

    The simulated arm has none of them fitted: /joint_states carries each at rest at 0 (within
    its limits), since MoveIt's robot model (and robot_state_publisher's) has every joint of the
    URDF. The URDF is ``urdf_path``, or the shipped one.
    """
    root = ET.parse(urdf_path or os.path.join(CONFIG_DIR, 'mover6.urdf')).getroot()
    out = {}
    for joint in root.findall('joint'):
        if joint.get('type') == 'fixed' or joint.get('name') in arm.joint_names:
            continue
        limit = joint.find('limit')
        lower = float(limit.get('lower', 0.0)) if limit is not None else 0.0
        upper = float(limit.get('upper', 0.0)) if limit is not None else 0.0
        out[joint.get('name')] = min(max(0.0, lower), upper) if lower <= upper else 0.0
    return out


def pacing_from_parameters(p: dict, config: SimConfig) -> Pacing:
    """Return the ``Pacing`` of the parameters ``p`` (name: value); raise when invalid."""
    rtf = float(p['real_time_factor'])
    if not (np.isfinite(rtf) and rtf >= 0.0):
        raise InvalidInputError(f'real_time_factor must be >= 0, got {rtf}')
    rate = float(p['publish_rate'])
    if not (0.0 < rate <= MAX_PUBLISH_RATE):
        raise InvalidInputError(
            f'publish_rate must be in (0, {MAX_PUBLISH_RATE}] Hz, got {rate}')
    vendor = config.mode == 'vendor_driver'
    return Pacing(dt=config.physics_dt, rtf=rtf,
                  publish_period=config.vendor_cycle if vendor else 1.0 / rate,
                  rest_period=1.0 / float(p['rest_publish_rate']),   # at least publish_period
                  vendor=vendor, publish_clock=bool(p['publish_clock']),
                  priority=int(p['physics_priority']))


def open_viewer(sim: Simulator, logger: Any) -> Optional[Any]:
    """Return a passive MuJoCo viewer, or None (with a warning) when there is no display."""
    if not (os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')):
        logger.warning('viewer asked for but no display: running headless')
        return None
    try:
        import mujoco.viewer
        return mujoco.viewer.launch_passive(sim.model, sim.data)
    except Exception as exc:  # noqa: B902 - any GL/GLFW failure: stay headless
        logger.warning(f'viewer failed ({exc}): running headless')
        return None


class SimJogIntake:
    """
    /JointJog (serialized) into the simulator: read, validate, hand over; count refusals.

    The same command as the last one taken (the controller at rest sends zeros every tick)
    only restarts its timeout, at the sim time the steps due would reach
    (``PhysicsThread.refresh``): the steps run at the next wake-up as they would have, without
    a wake-up of their own.
    """

    def __init__(self, physics: PhysicsThread, rejections: Rejections, logger: Any):
        """Hand commands to ``physics``; count refusals in ``rejections``."""
        self.physics = physics
        self.rejections = rejections
        self.logger = logger
        self.reader = cdr.JointJogReader()
        self.last = None                 # (names, velocities) of the last command taken

    def take(self, raw: bytes) -> None:
        """Take one /JointJog; a refused one raises (the guard logs and counts it)."""
        arrival = time.monotonic()
        try:
            try:
                names, _, values = self.reader.read_jog(raw)
                if (names, values) == self.last and self.physics.refresh(arrival):
                    return
            except ValueError:
                pass                     # conversions reads it (or says why not)
            jog = conversions.joint_jog_from_raw(raw, self.reader)   # checked once, here
            warnings = self.physics.command(jog, arrival)
            self.last = (tuple(jog.names), tuple(jog.velocities))
        except InvalidInputError as exc:
            self.rejections.add(str(exc))
            raise                        # refused: the guard logs and counts it
        for text in warnings:
            self.logger.warning(f'/JointJog speed clamped: {text}', throttle_duration_sec=1.0)


class SimBridgeNode(Node):
    """The simulated arm on ROS 2; see the module docstring."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the simulator and its parts, start the physics."""
        super().__init__('sim_bridge', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        # Refuses invalid values, each and as the simulator's config, at start and later.
        params.declare(self, SIM_BRIDGE, sim_config_from_parameters, guard=self.guard)
        self.guard.after_set(self.on_parameters_set)
        p = {name: self.get_parameter(name).value for name in SIM_BRIDGE}
        self.arm = make_arm(p['limit_set'], p['urdf_path'])
        self.unfitted = unfitted_joints(self.arm, p['urdf_path'])
        config = sim_config_from_parameters(p.get)
        self.pacing = pacing_from_parameters(p, config)
        self.sim = Simulator(self.arm, config, home_q=list(p['initial_q']))
        self.rejections = Rejections()
        self.physics = PhysicsThread(self.sim, self.pacing, self.make_outputs(), self.rejections)
        self.controls = SimControls(self.physics, self.arm.joint_names, self.get_logger())
        self.jogs = SimJogIntake(self.physics, self.rejections, self.get_logger())
        self.guard.subscription(JointJog, 'JointJog', self.jogs.take, STREAM_READER_QOS,
                                raw=True)
        self.guard.subscription(JointState, '~/reset_to', self.on_reset_to, 10)
        self.guard.service(Trigger, '~/reset', self.on_reset)
        self.guard.service(SetBool, '~/pause', self.on_pause)
        self.guard.service(Trigger, '~/step', self.on_step)
        if p['viewer']:
            self.physics.viewer = open_viewer(self.sim, self.get_logger())
        self.physics.start()
        pacing = self.pacing
        self.get_logger().info(
            f'{self.arm.name}: mode {config.mode}, physics_dt {pacing.dt} s, real-time factor '
            f'{pacing.rtf}, /joint_states every {pacing.publish_period:.4f} s'
            + ('' if pacing.vendor or pacing.rest_period <= pacing.publish_period else
               f' ({pacing.rest_period:.4f} s while the arm rests)') + ', command timeout '
            f'{config.command_timeout} s' + (', publishing /clock' if pacing.publish_clock
                                             else ''))

    def make_outputs(self) -> BridgeOutputs:
        """Return the publishers of /joint_states, /clock, ~/status and ~/contacts."""
        # /joint_states go as bytes (cdr): building and converting a message object per sample
        # was most of the idle bridge's CPU; /JointJog is read from its bytes likewise.
        contacts = self.create_publisher(DiagnosticStatus, '~/contacts', STATUS_QOS)
        joint_states = self.create_publisher(JointState, 'joint_states', 10)
        status = self.create_publisher(DiagnosticStatus, '~/status', STATUS_QOS)
        clock = (self.create_publisher(Clock, 'clock', 10) if self.pacing.publish_clock
                 else None)
        names = tuple(self.arm.joint_names) + tuple(self.unfitted)
        return BridgeOutputs(self.get_logger(), joint_states, status, contacts, clock,
                             cdr.JointStateWriter(names), self.get_clock(),
                             sim_stamps=self.pacing.publish_clock,
                             unfitted=tuple(self.unfitted.values()))

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        """
        Apply ``real_time_factor``, ``publish_rate`` and ``rest_publish_rate`` live.

        The pace re-anchors at the present time, so a new factor holds from now on; the next
        /joint_states comes at most one new period of sim time after the change (vendor_driver
        publishes at the driver's cycle, whatever ``publish_rate`` says).
        """
        self.physics.wake.set()          # the next wake-up is computed anew
        for parameter in parameters:
            if parameter.name == 'real_time_factor':
                self.physics.set_rtf(float(parameter.value))
            elif parameter.name == 'publish_rate' and not self.pacing.vendor:
                self.physics.set_periods(publish_period=1.0 / float(parameter.value))
            elif parameter.name == 'rest_publish_rate' and not self.pacing.vendor:
                self.physics.set_periods(rest_period=1.0 / float(parameter.value))
            else:
                continue
            self.get_logger().info(f'{parameter.name} {parameter.value}: in force')

    # --- callbacks ---------------------------------------------------------------------------

    def on_reset_to(self, msg: JointState) -> None:
        """Reset to the positions of a JointState (by name; unnamed joints go home; or refused)."""
        self.controls.reset_to(self.controls.named_positions(list(msg.name),
                                                             list(msg.position)))

    def on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Reset to ``initial_q``, at rest, commands dropped."""
        self.controls.reset_to(None)
        response.success = True
        response.message = f'reset to {np.round(self.sim.home_q, 4).tolist()}'
        return response

    def on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        """Pause (data true) or resume (data false) the physics."""
        t = self.controls.pause(bool(request.data))
        response.success = True
        response.message = f'{"paused" if request.data else "running"} at t = {t:.4f} s'
        self.get_logger().info(response.message)
        return response

    def on_step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """While paused, run one control period and publish; refuse when running."""
        response.success = self.physics.paused
        if not self.physics.paused:
            response.message = 'not paused: ~/pause first'
            return response
        n = self.controls.step_period()
        response.message = f'stepped {n} x {self.pacing.dt} s to t = {self.sim.time:.4f} s'
        return response

    def destroy_node(self) -> None:
        """Stop the physics thread and the viewer, then destroy the node."""
        self.physics.stop()
        return super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Run the sim_bridge node until Ctrl-C, SIGTERM or shutdown (one or more signals: exit 0)."""
    shutdown.run_node(SimBridgeNode, args)


if __name__ == '__main__':
    main()
