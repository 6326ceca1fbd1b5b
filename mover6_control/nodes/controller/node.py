"""
The controller node: joint waypoints and joint states in, one JointJog per tick out.

Subscribes /joint_states (sensor_msgs/JointState, mapped by name) and /joint_demands
(std_msgs/Float32MultiArray, N x 6 with layout or flat); publishes /JointJog
(control_msgs/JointJog: all six joints, stamped, velocities only) at ``rate`` on the node's clock
and /controller/status (diagnostic_msgs/DiagnosticStatus, transient local, on every change and at
``status_rate``). Services ~/stop and ~/reset (std_srvs/Trigger); the action
~/follow_joint_trajectory (control_msgs/FollowJointTrajectory, ``trajectory_server``). A demand may
name the goal it is for (``layout.dim[0].label`` = ``waypoints goal <id>``, as the planner writes
it): it is then answered on controller/demand_acks (actionlib_msgs/GoalStatus: received, taken,
refused or not ready; ``demand_answers``), and the status carries it as ``goal_id`` next to the
``motion_id`` it became (``goal_ledger``). A label ending in ``profile <name>`` times that demand
with its own profile (``motion_profile`` in the status; the ``profile`` parameter does not change).
Jogging, as MoveIt Servo names it: ~/delta_twist_cmds (geometry_msgs/TwistStamped, flange twist in
base_link or link6) and ~/delta_joint_cmds (control_msgs/JointJog, velocities by name) drive the
arm live (``control.servo``); a refused command is logged and its reason is the status value
``jog_refused``. A jog command stamped in the future of its arrival is refused; each goes stale
``servo_command_timeout`` after the earlier of its stamp and its arrival.

All the logic is in ``control.controller_core``; the node converts, calls it, publishes. For the
Mover6's vendor driver set ``jog_units`` to fraction_of_max (``driver_tick_size`` and
``driver_cycle``: the goal tolerance is then one encoder tick).

The node is built from parts, each a class given what it uses: the /JointJog output
(``jog_output``), the status (``status_publisher``, with the tick's ``tick_figures``), the answers
to goal demands (``demand_answers``), the tick thread (``tick_loop``), the demand thread
(``demand_thread``; large demands are planned in ``plan_worker``'s process), the check for a second
/joint_states publisher (``states_sources``) and the action server's thread (``action_thread``, on
a node of its own). The lock rule: the core and the goal ledger are read and changed only under
``lock``; nothing slow or published.
"""

import threading
from typing import Callable, Optional

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from mover6_control.control.collision_guard import CollisionGuard
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.controller.action_thread import ActionThread
from mover6_control.nodes.controller.demand_answers import DemandAnswers
from mover6_control.nodes.controller.demand_thread import DemandThread
from mover6_control.nodes.controller.goal_ledger import GoalLedger
from mover6_control.nodes.controller.jog_output import JogOutput
from mover6_control.nodes.controller.plan_worker import PlanWorker
from mover6_control.nodes.controller.states_sources import StatesSources
from mover6_control.nodes.controller.status_publisher import StatusPublisher
from mover6_control.nodes.controller.tick_figures import TickFigures
from mover6_control.nodes.controller.tick_loop import TickLoop
from mover6_control.nodes.controller.trajectory_server import ControllerParts
from mover6_control.nodes.messages import cdr, conversions, demand_messages
from mover6_control.nodes.runtime import params, shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.nodes.runtime.node_configs import (check_where_it_stands, collision_settings,
                                                       config_from_parameters, standing_check)
from mover6_control.nodes.runtime.qos import STATUS_QOS, STREAM_READER_QOS
from mover6_control.parameters import CONTROLLER
from mover6_control.realtime import steady_interpreter
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
from std_srvs.srv import Trigger

# Longest waits [s] at shutdown: for the readers of /JointJog to acknowledge the last zero
# command, and for the tick and demand threads to end.
ZERO_ACK_TIMEOUT = THREADS_JOIN_TIMEOUT = 1.0


class ControllerNode(Node):
    """Drive the arm through joint waypoints with one JointJog per tick; see the module doc."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the core and the parts, start the threads."""
        super().__init__('controller', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (bad input: refused)
        # Refuses invalid values (each, and the whole config: check_config) before a set; an
        # accepted set goes to the core (at once, or after the motion).
        self.standing, self.started = standing_check(), False   # the collision parameters
        params.declare(self, CONTROLLER, self.check_config, guard=self.guard)
        self.started = True
        limit_set, config = config_from_parameters(lambda n: self.get_parameter(n).value)
        self.guard.after_set(self.on_parameters_set)
        self.lock = threading.RLock()        # the core's state and the goal ledger
        self.core = ControllerCore(mover6(limit_set), config)
        self.goals = GoalLedger(self.lock)   # which motion each goal became, or why not
        self.apply_collision_parameters()
        self.joint_names = list(self.core.arm.joint_names)
        self.last_q = None          # the latest valid joint positions, for the action server
        self.destroyed, self.has_states = False, threading.Event()   # set: valid states
        self.states_reader = cdr.JointStateReader()   # /joint_states read as bytes (cdr)
        clock_ns = lambda: now_ns(self.get_clock())   # noqa: E731

        jog_pub, figures = self.create_publisher(JointJog, 'JointJog', 10), TickFigures()
        self.jog = JogOutput(jog_pub, self.joint_names, clock_ns)
        self.status = StatusPublisher(
            self.create_publisher(DiagnosticStatus, 'controller/status', STATUS_QOS),
            self.core, self.lock, self.goals, figures, status_period(self.get_parameter))
        self.answers = DemandAnswers(self, clock_ns)
        self.plan_worker = PlanWorker(start=False)   # started by the first large demand
        self.ticks = TickLoop(self.core, self.lock, self.get_clock(), self.context,
                              self.get_logger(), self.jog, self.status, figures, self.has_states,
                              self.get_parameter('tick_priority').value)
        self.demand_thread = DemandThread(
            self.core, self.lock, self.goals, self.answers, self.status.publish,
            self.has_states, self.plan_worker, self.now, self.get_logger(), self.guard,
            self.resolve_topic_name('joint_demands'))

        self.guard.subscription(JointState, 'joint_states', self.on_joint_states,
                                STREAM_READER_QOS, raw=True)
        self.guard.subscription(Float32MultiArray, 'joint_demands', self.on_demands, 10)
        self.guard.subscription(TwistStamped, '~/delta_twist_cmds', self.on_twist, 10)
        self.guard.subscription(JointJog, '~/delta_joint_cmds', self.on_joint_jog, 10)
        self.guard.service(Trigger, '~/stop', self.on_stop)
        self.guard.service(Trigger, '~/reset', self.on_reset)
        self.sources = StatesSources(self, 'joint_states', self.core, self.lock, self.guard,
                                     self.now)   # a second publisher of the states: hold
        # The action server (its own node and thread), with what it uses of the controller.
        self.actions = ActionThread(self, ControllerParts(
            tuple(self.joint_names), self.core, self.lock, self.goals, self.demand_thread.put,
            self.guard, self.get_clock(), self.get_logger(), self.now, lambda: self.running,
            lambda: self.last_q, lambda name: self.get_parameter(name).value))

        # Started once every part exists (a real-time tick runs at once); the others first, so
        # the tick's raise puts them one below (realtime.py).
        self.log_start(limit_set, config)
        self.demand_thread.start()
        self.actions.start()
        self.ticks.start()
        self.status.publish(self.now())

    @property
    def running(self) -> bool:
        """Return whether the controller still runs (not closed, its tick not given up)."""
        return not self.destroyed and self.ticks.running

    @property
    def fatal(self) -> Optional[str]:
        """Return why the tick cannot run (the process exits with 1), or None."""
        return self.ticks.fatal

    def log_start(self, limit_set: str, config: ControllerConfig) -> None:
        """Say what the controller runs with (before its threads start: no lock needed)."""
        ticks = ('' if config.jog_units != 'fraction_of_max' else ' (whole ticks; goal tolerance '
                 + ' '.join(f'{t:.4f}' for t in self.core.goal_tolerance) + ' rad)')
        self.get_logger().info(
            f'controller: {config.law.profile} at {config.rate:g} Hz, jog_units '
            f'{config.jog_units}{ticks}, limit_set {limit_set}; waiting for /joint_states')

    def now(self) -> float:
        """Return the node clock's time [s] (sim time when use_sim_time is set)."""
        return now_ns(self.get_clock()) * 1e-9

    def check_config(self, get: Callable[[str], object]) -> None:
        """
        Raise saying why the parameters of ``get(name)`` make no valid controller config.

        ``params.declare`` calls it on the values a set would leave in force, before the set
        is accepted: the config, the collision check's settings (tool size, keep-out boxes; none
        that puts the arm in collision where it stands: the latest joint states, at start the
        start configuration, ``node_configs.check_where_it_stands``) and, once the core exists,
        the config against the arm (one driver tick per joint ...).
        """
        _, config = config_from_parameters(get)
        check_where_it_stands(self.standing, get, getattr(self, 'last_q', None),
                              (lambda n: self.get_parameter(n).value) if self.started else None)
        core = getattr(self, 'core', None)
        if core is not None:
            core.check_config(config)

    def on_parameters_set(self, parameters: list[Parameter]) -> None:
        """
        Apply parameters just set: to the core now, or when the running motion ends.

        Cannot fail: ``check_config`` built all of it from these values before the set.
        """
        if not any(p.name in CONTROLLER for p in parameters):
            return
        names = ', '.join(f'{p.name} {p.value}' for p in parameters)
        _, config = config_from_parameters(lambda n: self.get_parameter(n).value)
        self.status.period = status_period(self.get_parameter)
        self.apply_collision_parameters()
        with self.lock:
            now_applied = self.core.reconfigure(config)
            self.ticks.note_pending(not now_applied)
        if now_applied:
            self.get_logger().info(f'parameters in force: {names}')
        else:
            self.get_logger().info(f'parameters set ({names}): applies to the next motion')
        self.status.publish(self.now())

    def apply_collision_parameters(self) -> None:
        """Give the core the collision check of the parameters (None when it is off)."""
        get = self.get_parameter
        settings = collision_settings(lambda n: get(n).value)
        with self.lock:
            guard = self.core.collision_guard
        if guard is None or guard.settings != settings:
            guard = CollisionGuard(self.core.arm, settings) if settings.enabled else None
            with self.lock:          # built outside it (it loads the arm's shapes)
                self.core.collision_guard = guard

    def on_joint_states(self, raw: bytes) -> None:
        """
        Hand a serialized JointState's names, positions and velocities to the core's robot.

        Other joints (a gripper) are ignored; a missing or repeated joint or a non-finite value
        makes the states invalid with that reason: the core faults. A sample that cannot be read
        is refused (the guard logs and counts it; the states go stale if no other comes).
        """
        now = self.now()
        fields = conversions.joint_state_fields_from_raw(raw, self.states_reader)
        with self.lock:
            self.core.on_named_joint_states(now, *fields)   # names, positions, velocities
            self.last_q = self.core.robot.q

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Say that a demand naming a goal came; hand it to the demand thread (it plans there)."""
        goal_id = demand_messages.demand_id_from_msg(msg)
        if goal_id:
            self.answers.received(goal_id)
        self.demand_thread.put(msg)

    def on_twist(self, msg: TwistStamped) -> None:
        """Take a jog twist (~/delta_twist_cmds) or say why not."""
        now = self.now()
        try:
            stamp, linear, angular, frame = conversions.twist_command_from_msg(msg, now)
            with self.lock:
                self.core.on_twist(now, stamp, linear, angular, frame)
        except InvalidInputError as err:
            with self.lock:
                self.core.note_jog_refused(str(err))
            raise                   # refused: the guard logs and counts it

    def on_joint_jog(self, msg: JointJog) -> None:
        """Take a joint jog (~/delta_joint_cmds) or say why not."""
        now = self.now()
        try:
            stamp, names, velocities = conversions.joint_jog_command_from_msg(msg, now)
            with self.lock:
                self.core.on_joint_jog(now, stamp, names, velocities)
        except InvalidInputError as err:
            with self.lock:
                self.core.note_jog_refused(str(err))
            raise                   # refused: the guard logs and counts it

    def on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Decelerate to rest and hold (std_srvs/Trigger)."""
        with self.lock:
            response.success, response.message = self.core.request_stop(self.now())
        self.get_logger().info(f'stop: {response.message}')
        return response

    def on_reset(self, request: Trigger.Request,
                 response: Trigger.Response) -> Trigger.Response:
        """Leave fault and wait for fresh joint states (std_srvs/Trigger)."""
        with self.lock:
            self.core.reset(self.now())
            response.success, response.message = True, f'state {self.core.state}'
        return response

    def destroy_node(self) -> None:
        """Stop the tick and demand threads, send a last zero command, then destroy the node."""
        if self.destroyed:
            return
        self.destroyed = True
        self.ticks.running = False
        self.demand_thread.stop()
        self.plan_worker.close()    # a demand planned there is refused: its thread can end
        self.demand_thread.close(THREADS_JOIN_TIMEOUT)   # a demand waiting for states: ends
        self.goals.close()          # an action goal waiting for its demand stops waiting
        self.actions.close()        # its thread ends, then its server and node
        self.ticks.close(THREADS_JOIN_TIMEOUT)
        if self.context.ok():
            self.jog.send_zero()
            # else the writer's end drops an unacknowledged zero (lost in 2 of 7, test_shutdown)
            self.jog.wait_for_all_acked(ZERO_ACK_TIMEOUT)
        super().destroy_node()


def status_period(get: Callable[[str], Parameter]) -> float:
    """Return the period [s] of the status from the parameter ``status_rate``."""
    return 1.0 / max(get('status_rate').value, 1e-3)


def main(args: Optional[list[str]] = None) -> None:
    """
    Run the controller node until Ctrl-C, SIGTERM or shutdown; then send a zero command.

    rclpy's own signal handlers would shut the context down before the node could publish that
    zero (and the vendor driver keeps the last command forever); ``shutdown.run_node`` keeps the
    context valid until ``destroy_node()`` has sent it, and ignores any further signal meanwhile.
    """
    # The tick gets the interpreter 0.5 ms after its deadline, not 5 ms (bench controller); what
    # is loaded now is never scanned by a full collection (a 10,000-point goal makes 40,000).
    steady_interpreter()
    shutdown.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
