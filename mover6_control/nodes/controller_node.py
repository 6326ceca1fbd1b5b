"""
The controller node: joint waypoints and joint states in, one JointJog per tick out.

Subscribes /joint_states (sensor_msgs/JointState, mapped by name) and /joint_demands
(std_msgs/Float32MultiArray, N x 6 with layout or flat); publishes /JointJog
(control_msgs/JointJog: all six joints, stamped, velocities only) at ``rate`` on the node's clock
and /controller/status (diagnostic_msgs/DiagnosticStatus, transient local, on every change and
at ``status_rate``). Services ~/stop and ~/reset (std_srvs/Trigger); the action
~/follow_joint_trajectory (control_msgs/FollowJointTrajectory, ``trajectory_action``). A demand
may name the goal it is for (``layout.dim[0].label`` = ``waypoints goal <id>``, as the planner
writes it): the status then carries it as ``goal_id`` next to the ``motion_id`` it became. A
label ending in ``profile <name>`` times that demand with its own law (``motion_profile`` in the
status; the ``profile`` parameter does not change).
Jogging, as MoveIt Servo names it: ~/delta_twist_cmds (geometry_msgs/TwistStamped, flange
twist in base_link or link6) and ~/delta_joint_cmds (control_msgs/JointJog, velocities by name)
drive the arm live (``control.servo``); a refused command is logged and its reason is the
status value ``jog_refused``.
All the logic is
in ``mover6_control.control.controller_core``, whose model of the arm is a
``control.robot.Robot`` (``self.core.robot``): the node hands each /joint_states message's
names, positions and velocities to it (mapped by name there), converts demands, calls the core
and publishes. For
the Mover6's vendor driver set ``jog_units`` to fraction_of_max; ``driver_tick_size`` and
``driver_cycle`` (defaults: the Mover6's) let the core move joints that a command under one
encoder tick per cycle would leave standing, and widen the goal tolerance to one tick.

The tick runs in its own thread that sleeps on the node's clock (``Clock.sleep_until``, so sim
time works): that costs less CPU and jitter than an executor timer; the executor thread serves
the callbacks, and a lock keeps the core consistent between the two. Nothing slow happens under
that lock. Demands are planned in a third thread, in the order they came: the continuous law
plans a long path for tens of milliseconds, hundreds on a loaded machine, and neither the ticks
nor the /joint_states callback may wait that long (states unread for ``state_timeout`` fault the
controller); a plan that the controller moved on from meanwhile is made again, also outside the
lock. JointJog and status are published outside it too: a DDS write can block. Measured
(``bench/bench_churn.py``): Fast DDS 2.14 holds one send lock per participant, and its discovery
thread holds it while it opens the shared-memory port of a process that just joined the graph,
which can take 333 ms (eProsima/Fast-DDS issue 6535); every write of the node waits that long.

The status value ``max_tick_gap`` [s] is the longest time between two ticks since the node
started (node clock; nominal ``1 / rate``), and a tick later than ``TICK_GAP_WARN`` logs a
warning, so a stalled tick thread shows in the controller and not only as a stale command at the
driver. To see what held it up, set the environment variable ``MOVER6_TICK_WATCHDOG`` to a time
[s]: a tick later than that dumps the stack of every thread to stderr (``faulthandler``, which
needs no interpreter lock for it; wall time, so a paused sim clock trips it too).

The tick never dies: an exception inside it is a fault (zero command, the reason on the
status, cleared by fresh joint states as any fault); when ``MAX_TICK_FAILURES`` ticks in a row
raise, or the tick thread ends by an exception, the node gives up (``fatal``) and its process
exits with 1 after the last zero command, so the launcher sees it. A jog command whose stamp
lies in the future of its arrival is refused, and every jog command goes stale
``servo_command_timeout`` after the earlier of its stamp and its arrival (``control.servo``).
"""

import faulthandler
import os
import queue
import sys
import threading
import time
import traceback

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from mover6_control.control.collision_guard import CollisionGuard
from mover6_control.control.controller_core import ControllerConfig, ControllerCore
from mover6_control.control.profiles import LawConfig
from mover6_control.control.servo import ServoConfig
from mover6_control.control.state_machine import FAULT, WAITING_FOR_STATES
from mover6_control.errors import InvalidInputError, Mover6Error
from mover6_control.kinematics.arm import LIMIT_SETS, mover6
from mover6_control.nodes import conversions, params, shutdown
from mover6_control.nodes.qos import STATUS_QOS
from mover6_control.nodes.trajectory_action import FollowJointTrajectoryServer
from mover6_control.parameters import CONTROLLER
from mover6_control.realtime import run_at_priority
from mover6_control.validation import short_text
from rclpy.duration import Duration
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray
from std_srvs.srv import Trigger

# A tick this late [s] is logged: the driver (and the sim bridge) halt after 0.2 s without one.
TICK_GAP_WARN = 0.05
# Plans of one demand made without the lock before the last is committed as it is (re-planned
# under the lock when the controller moved on yet again: only when motions end that often).
DEMAND_ATTEMPTS = 3
# [s] a demand whose plan took longer than this is never planned again under the lock (the
# ticks would wait for it): refused with the reason instead when the controller moved on again.
LOCKED_PLAN_LIMIT = 0.02
WATCHDOG_ENV = 'MOVER6_TICK_WATCHDOG'
# Longest wait [s] at shutdown for the readers of /JointJog to acknowledge the last zero command.
ZERO_ACK_TIMEOUT = 1.0
# Ticks in a row that raised (each a fault with a zero command) after which the tick cannot run
# at all: the node gives up and its process exits with 1, so the launcher sees it.
MAX_TICK_FAILURES = 10
# Longest wait [s] of a demand that comes before the first joint states (the planner can be
# quicker at start-up), or in a fault that fresh states clear (a stall at start-up: Fast DDS
# discovery can hold a process for 0.33 s); then it is refused with the reason. Less than the
# planner's resend window (RESEND_AFTER * (RESENDS + 1) = 3 s).
DEMAND_STATE_WAIT = 2.0
# States in which a demand waits (DEMAND_STATE_WAIT) for valid joint states.
WAIT_FOR_STATES = (WAITING_FOR_STATES, FAULT)


def config_from_parameters(get):
    """Return ``(limit_set, ControllerConfig)`` from a parameter getter ``get(name)``."""
    law = LawConfig(profile=get('profile'), lambda_max=get('lambda_max'), t_max=get('t_max'),
                    t_blend=get('t_blend'), a_max=get('a_max'), j_max=get('j_max'))
    config = ControllerConfig(
        law=law, goal_tolerance=get('goal_tolerance'), state_timeout=get('state_timeout'),
        position_gain=get('position_gain'), settle_timeout=get('settle_timeout'),
        path_tolerance=get('path_tolerance'), rate=get('rate'), jog_units=get('jog_units'),
        speed_override=get('speed_override'), driver_tick_size=tuple(get('driver_tick_size')),
        driver_cycle=get('driver_cycle'), cycle_driver=get('cycle_driver'),
        settle_tolerance=get('settle_tolerance'),
        settle_time=get('settle_time'), servo=servo_config_from_parameters(get))
    limit_set = get('limit_set')
    if limit_set not in LIMIT_SETS:
        raise InvalidInputError(f'limit_set must be one of {LIMIT_SETS}, got {limit_set!r}')
    return limit_set, config


def servo_config_from_parameters(get):
    """Return the ``ServoConfig`` of the ``servo_*`` parameters (and ``a_max``)."""
    return ServoConfig(
        command_timeout=get('servo_command_timeout'), pose_gain=get('servo_pose_gain'),
        damping=get('servo_damping'),
        lower_singularity_threshold=get('servo_lower_singularity_threshold'),
        hard_stop_singularity_threshold=get('servo_hard_stop_singularity_threshold'),
        joint_limit_margin=get('servo_joint_limit_margin'), a_max=get('a_max'))


class ControllerNode(Node):
    """Drive the arm through joint waypoints with one JointJog per tick; see the module doc."""

    def __init__(self, **kwargs):
        """Declare the parameters, build the core, start the topics, services and tick thread."""
        super().__init__('controller', **kwargs)
        # Refuses invalid values, each and as a whole config (check_config), before a set is
        # accepted; an accepted set is handed to the core (at once, or after the motion).
        params.declare(self, CONTROLLER, self.check_config)
        limit_set, config = config_from_parameters(lambda n: self.get_parameter(n).value)
        self.add_post_set_parameters_callback(self.on_parameters_set)
        self.core = ControllerCore(mover6(limit_set), config)
        self.apply_collision_parameters()
        self.joint_names = list(self.core.arm.joint_names)
        self.status_period = 1.0 / max(self.get_parameter('status_rate').value, 1e-3)
        self.last_status = None
        self.jog_pub = self.create_publisher(JointJog, 'JointJog', 10)
        self.status_pub = self.create_publisher(DiagnosticStatus, 'controller/status',
                                                STATUS_QOS)
        self.create_subscription(JointState, 'joint_states', self.on_joint_states, 10)
        self.create_subscription(Float32MultiArray, 'joint_demands', self.on_demands, 10)
        self.create_subscription(TwistStamped, '~/delta_twist_cmds', self.on_twist, 10)
        self.create_subscription(JointJog, '~/delta_joint_cmds', self.on_joint_jog, 10)
        self.create_service(Trigger, '~/stop', self.on_stop)
        self.create_service(Trigger, '~/reset', self.on_reset)
        self.lock = threading.RLock()        # the core's state
        self.status_lock = threading.Lock()  # one status publication at a time (before lock)
        self.last_state = None           # the core's state after the latest tick
        self.has_states = threading.Event()  # set while the core has valid states
        self.last_tick = None            # node clock [ns] of the latest tick
        self.max_tick_gap = 0.0          # [s] longest time between two ticks so far
        self.running = True
        self.destroyed = False
        self.fatal = None                # why the tick cannot run: the process exits with 1
        self.tick_errors = 0             # ticks in a row that raised outside the core
        self.pending_logged = False      # 'applies to the next motion' said, not yet applied
        self.tick_thread = threading.Thread(target=self.run_ticks, daemon=True)
        self.demands = queue.SimpleQueue()   # /joint_demands messages not yet taken; None: end
        self.demand_thread = threading.Thread(target=self.demand_loop, daemon=True)
        # Goal ids (the planner's, or an action goal's) of the demands: echoed in the status.
        self.motion_goals = {}       # motion_id -> goal id ('' for none)
        self.goal_motions = {}       # goal id -> motion_id
        self.goal_rejections = {}    # goal id -> why its demand was refused
        self.withdrawn = set()       # goal ids whose action stopped waiting: never started
        self.motion_starts = {}      # motion_id -> node clock [s] its plan counts from
        self.last_q = None           # the latest valid joint positions, for the action
        self.trajectory_server = FollowJointTrajectoryServer(self)
        # Started once every attribute exists: a tick thread at real-time priority (tick_priority)
        # runs at once and publishes a status, which reads motion_goals (it raised before).
        self.tick_thread.start()
        self.demand_thread.start()
        ticks = ''
        if config.jog_units == 'fraction_of_max':
            ticks = (' (whole ticks; goal tolerance '
                     + ' '.join(f'{t:.4f}' for t in self.core.goal_tolerance) + ' rad)')
        self.get_logger().info(
            f'controller: {config.law.profile} at {config.rate:g} Hz, jog_units '
            f'{config.jog_units}{ticks}, limit_set {limit_set}; waiting for /joint_states')
        self.publish_status(self.now())

    def now(self):
        """Return the node clock's time [s] (sim time when use_sim_time is set)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def check_config(self, get):
        """
        Raise saying why the parameters of ``get(name)`` make no valid controller config.

        ``params.declare`` calls it on the values a set would leave in force, before the set
        is accepted: the config, the collision check's settings (tool size, keep-out boxes) and,
        once the core exists, the config against the arm (one driver tick per joint ...).
        """
        _, config = config_from_parameters(get)
        params.collision_settings(get)
        core = getattr(self, 'core', None)
        if core is not None:
            core.check_config(config)

    def on_parameters_set(self, parameters):
        """
        Apply parameters just set: to the core now, or when the running motion ends.

        Cannot fail: ``check_config`` built all of it from these values before the set.
        """
        if not any(p.name in CONTROLLER for p in parameters):
            return
        names = ', '.join(f'{p.name} {p.value}' for p in parameters)
        _, config = config_from_parameters(lambda n: self.get_parameter(n).value)
        self.status_period = 1.0 / max(self.get_parameter('status_rate').value, 1e-3)
        self.apply_collision_parameters()
        with self.lock:
            now_applied = self.core.reconfigure(config)
            self.pending_logged = not now_applied
        if now_applied:
            self.get_logger().info(f'parameters in force: {names}')
        else:
            self.get_logger().info(f'parameters set ({names}): applies to the next motion')
        self.publish_status(self.now())

    def apply_collision_parameters(self):
        """Give the core the collision check of the parameters (None when it is off)."""
        get = self.get_parameter
        settings = params.collision_settings(lambda n: get(n).value)
        if self.core.collision_guard is None or self.core.collision_guard.settings != settings:
            self.core.collision_guard = (CollisionGuard(self.core.arm, settings)
                                         if settings.enabled else None)

    def on_joint_states(self, msg):
        """
        Hand a JointState's names, positions and velocities to the core's robot (by name).

        Other joints (a gripper) are ignored; a missing or repeated joint, or a non-finite value,
        makes the states invalid with that reason: the core faults.
        """
        now = self.now()
        try:
            with self.lock:
                self.core.on_named_joint_states(now, msg.name, msg.position, msg.velocity)
                self.last_q = self.core.robot.q
        except InvalidInputError as err:
            self.get_logger().warning(f'bad /joint_states: {err}', throttle_duration_sec=1.0)

    def on_twist(self, msg):
        """Take a jog twist (~/delta_twist_cmds) or say why not."""
        now = self.now()
        try:
            stamp, linear, angular, frame = conversions.twist_command_from_msg(msg, now)
            with self.lock:
                self.core.on_twist(now, stamp, linear, angular, frame)
        except InvalidInputError as err:
            with self.lock:
                self.core.note_jog_refused(str(err))
            self.get_logger().warning(f'refused ~/delta_twist_cmds: {err}',
                                      throttle_duration_sec=1.0)

    def on_joint_jog(self, msg):
        """Take a joint jog (~/delta_joint_cmds) or say why not."""
        now = self.now()
        try:
            stamp, names, velocities = conversions.joint_jog_command_from_msg(msg, now)
            with self.lock:
                self.core.on_joint_jog(now, stamp, names, velocities)
        except InvalidInputError as err:
            with self.lock:
                self.core.note_jog_refused(str(err))
            self.get_logger().warning(f'refused ~/delta_joint_cmds: {err}',
                                      throttle_duration_sec=1.0)

    def on_demands(self, msg):
        """Hand a /joint_demands message to the demand thread (it plans there)."""
        self.demands.put(msg)

    def demand_loop(self):
        """
        Take the queued demands in order until ``None`` comes (the node closes).

        An item is a /joint_demands message, ``(message, Timing)`` (a goal's ``time_from_start``
        and velocities, ``control.timed_plan``), or a callable from the action server that
        returns one of those, or None when it refused the goal: a goal of 10,000 points is
        converted here, not in the executor thread that must keep taking /joint_states.
        """
        while True:
            msg = self.demands.get()
            if msg is None or not self.running:
                return
            if callable(msg):
                msg = msg()
                if msg is None:
                    continue
            msg, timing = msg if isinstance(msg, tuple) else (msg, None)
            self.take_demand(msg, timing)   # never raises: refuses with a reason instead

    def take_demand(self, msg, timing=None):
        """
        Accept waypoints or say why not: every demand ends accepted or refused with a reason.

        The one concurrency rule (docs/architecture.md, "Threads"): a snapshot of the core is
        taken under the lock, the plan is made from it without the lock (the ticks go on), and
        it is committed under the lock only if the snapshot is still current; otherwise it is
        planned again from a new snapshot (the last attempt re-plans under the lock, unless the
        plans take longer than ``LOCKED_PLAN_LIMIT``: then it is refused). The waypoints are
        checked before the first snapshot (a refusal names the state the snapshot saw), and a
        goal its action gave up waiting for (``withdrawn``) is never started.
        """
        now = self.now()
        goal_id = conversions.demand_id_from_msg(msg)
        if goal_id and (goal_id in self.goal_motions or goal_id in self.goal_rejections):
            # The planner sends a demand again until this status names its goal: take it once.
            self.get_logger().info(f'goal {goal_id}: demand received again; already taken')
            self.publish_status(now)
            return
        try:
            Q = conversions.demands_from_msg(msg, len(self.joint_names))
            profile = conversions.demand_profile_from_msg(msg)   # this demand's law only
            if self.core.state in WAIT_FOR_STATES:   # no valid states yet: wait a moment
                self.has_states.wait(DEMAND_STATE_WAIT)
                now = self.now()
            Q = self.core.check_demand(Q)       # the arm's limits only: no lock needed
            for attempt in range(DEMAND_ATTEMPTS):
                with self.lock:
                    snapshot = self.core.snapshot()
                started = time.monotonic()
                pending = self.core.prepare_demand(now, Q, snapshot, goal_id, timing=timing,
                                                   profile=profile)
                slow = time.monotonic() - started > LOCKED_PLAN_LIMIT
                with self.lock:
                    if goal_id and goal_id in self.withdrawn:
                        raise InvalidInputError(f'goal {goal_id}: its sender stopped waiting')
                    current = self.core.is_current(pending)
                    if not current and slow and attempt + 1 == DEMAND_ATTEMPTS:
                        raise InvalidInputError(
                            f'the controller moved on while this demand was planned, '
                            f'{DEMAND_ATTEMPTS} times; send it again')
                    if attempt + 1 == DEMAND_ATTEMPTS or current:
                        # From rest the plan starts now, not when its (long) planning began.
                        start = pending.now if pending.moving else self.now()
                        motion_id = self.core.commit_demand(pending, start)
                        self.motion_goals[motion_id] = goal_id
                        self.motion_starts[motion_id] = start
                        if goal_id:
                            self.goal_motions[goal_id] = motion_id
                        break
                now = self.now()
        except Exception as err:  # noqa: B902 - no demand is dropped without a status
            reason = str(err) if isinstance(err, Mover6Error) else f'{type(err).__name__}: {err}'
            reason = short_text(reason)   # hostile demands quote little
            self.get_logger().warning(f'rejected /joint_demands: {reason}')
            if goal_id:
                self.goal_rejections[goal_id] = reason
            with self.lock:
                self.core.reject(now, reason, goal_id)
            self.publish_status(now, level='WARN', message=f'rejected demand: {reason}')
            return
        self.get_logger().info(f'motion {motion_id}: {len(Q)} waypoint(s) accepted'
                               + (f' (goal {goal_id})' if goal_id else ''))
        self.publish_status(now)

    def on_stop(self, request, response):
        """Decelerate to rest and hold (std_srvs/Trigger)."""
        with self.lock:
            response.success, response.message = self.core.request_stop(self.now())
        self.get_logger().info(f'stop: {response.message}')
        return response

    def on_reset(self, request, response):
        """Leave fault and wait for fresh joint states (std_srvs/Trigger)."""
        with self.lock:
            self.core.reset(self.now())
        response.success, response.message = True, f'state {self.core.state}'
        return response

    def tick_loop(self):
        """Call ``on_tick`` every ``1 / rate`` [s] of the node's clock until the node closes."""
        self.set_tick_priority(self.get_parameter('tick_priority').value)
        clock = self.get_clock()
        deadline = clock.now()
        watchdog = float(os.environ.get(WATCHDOG_ENV) or 0.0)
        while self.running and self.context.ok():
            period = 1.0 / self.core.config.rate      # the rate in force: set live
            step = Duration(seconds=period)
            if watchdog > 0.0:
                faulthandler.dump_traceback_later(watchdog + period)   # re-armed each tick
            deadline = deadline + step
            if not clock.sleep_until(deadline, self.context):
                deadline = clock.now()          # clock switched (sim time) or shutting down
                self.last_tick = None           # no gap across the switch
                continue
            now = clock.now()
            if (now - deadline).nanoseconds > step.nanoseconds:
                deadline = now                  # fell behind by a whole period: no burst
            if self.running:
                self.run_tick()
        if watchdog > 0.0:
            faulthandler.cancel_dump_traceback_later()

    def run_ticks(self):
        """Run ``tick_loop`` (the tick thread); if it ends by an exception the node gives up."""
        try:
            self.tick_loop()
        except Exception as err:  # noqa: B902 - a dead tick thread must not go unnoticed
            self.give_up(f'the tick thread died: {type(err).__name__}: {err}',
                         traceback.format_exc())

    def run_tick(self):
        """
        Run ``on_tick``; a tick that raised is a fault, ``MAX_TICK_FAILURES`` in a row fatal.

        The core turns an exception in its tick into a fault itself (zero command, the reason
        on the status) and counts them; one here (publishing, the status) sends a zero command.
        """
        try:
            self.on_tick()
        except Exception as err:  # noqa: B902 - the tick goes on, the arm held
            self.tick_errors += 1
            self.get_logger().error(f'tick failed: {type(err).__name__}: {err}',
                                    throttle_duration_sec=1.0)
            try:
                self.send_zero()
            except Exception:  # noqa: B902 - giving up below if this keeps happening
                pass
        else:
            self.tick_errors = 0
        failures = self.core.tick_failures
        if failures >= MAX_TICK_FAILURES:
            with self.lock:
                last = self.core.status().message
            self.give_up(f'{failures} ticks in a row failed ({last})')
        elif self.tick_errors >= MAX_TICK_FAILURES:
            self.give_up(f'{self.tick_errors} ticks in a row failed to publish')

    def give_up(self, reason, details=''):
        """Stop ticking for good: log ``reason``, send a zero command, let the process exit 1."""
        self.fatal = reason
        self.running = False
        log = f'{reason}; the controller stops'
        self.get_logger().fatal(f'{log}\n{details}' if details else log)
        try:
            self.send_zero()
        except Exception:  # noqa: B902 - destroy_node sends one more
            pass

    def set_tick_priority(self, priority):
        """
        Run the tick thread at real-time priority ``priority`` (SCHED_FIFO), the rest just below.

        ``mover6_control.realtime.run_at_priority`` (the driver's cycle uses it too); 0: as is.
        Where the system refuses it, say so once and go on with normal scheduling.
        """
        if priority <= 0:
            return
        ok, message = run_at_priority(priority)
        if ok:
            self.get_logger().info(f'tick thread at {message}')
        else:
            self.get_logger().warning(f'tick_priority {priority}: {message}')

    def destroy_node(self):
        """Stop the tick thread, send a last zero command, then destroy the node."""
        if self.destroyed:
            return
        self.destroyed = True
        self.running = False
        self.demands.put(None)
        self.has_states.set()       # a demand waiting for states stops waiting
        self.trajectory_server.destroy()
        for thread in (self.tick_thread, self.demand_thread):
            if thread.is_alive() and thread is not threading.current_thread():
                thread.join(timeout=1.0)
        if self.context.ok():
            self.send_zero()
            # Destroying the writer at once drops a sample not yet acknowledged: the driver
            # would never see the zero (2 of 7 stops in test_shutdown.py lost it).
            self.jog_pub.wait_for_all_acked(Duration(seconds=ZERO_ACK_TIMEOUT))
        super().destroy_node()

    def on_tick(self):
        """Run one control tick: publish the JointJog, and the status when due."""
        time_now = self.get_clock().now()
        now = time_now.nanoseconds * 1e-9
        gap = self.note_tick(time_now.nanoseconds)
        with self.lock:
            out = self.core.tick(now)
            fault_change = None
            if (out.state == FAULT) != (self.last_state == FAULT):
                fault_change = self.core.status().message
            if out.state in WAIT_FOR_STATES:
                if self.last_state not in WAIT_FOR_STATES:
                    self.has_states.clear()
            elif self.last_state is None or self.last_state in WAIT_FOR_STATES:
                self.has_states.set()
            self.last_state = out.state
            applied = self.pending_logged and self.core.pending_config is None
            if applied:
                self.pending_logged = False
            status_due = (out.status_changed or self.last_status is None
                          or now - self.last_status >= self.status_period
                          or now < self.last_status)
        if applied:
            self.get_logger().info(f'parameters in force from now: {self.core.config.law.profile}'
                                   f' at {self.core.config.rate:g} Hz')
        if fault_change is not None:        # entering fault and leaving it: logged once each
            if out.state == FAULT:
                self.get_logger().error(f'fault: {fault_change}')
            else:
                self.get_logger().info(f'fault cleared ({out.state}): {fault_change}')
        # Published without the lock: a DDS write can block (seen for 0.33 s right after start-up
        # while the sim bridge was being matched), and the callbacks must not wait for it.
        self.jog_pub.publish(
            conversions.make_joint_jog(self.joint_names, out.jog, time_now.to_msg()))
        if gap > TICK_GAP_WARN:         # logged after the command went, not before it
            self.get_logger().warning(
                f'tick {gap * 1e3:.0f} ms after the one before (period '
                f'{1e3 / self.core.config.rate:.0f} ms): the tick thread stalled',
                throttle_duration_sec=1.0)
        if status_due:
            self.publish_status(now)

    def note_tick(self, stamp_ns):
        """Record a tick at ``stamp_ns`` [ns] of the node clock; return the gap [s] (0 first)."""
        last, self.last_tick = self.last_tick, stamp_ns
        if last is None or stamp_ns < last:          # first tick, or the clock went back
            return 0.0
        gap = (stamp_ns - last) * 1e-9
        self.max_tick_gap = max(self.max_tick_gap, gap)
        return gap

    def send_zero(self):
        """Publish a zero JointJog (the vendor driver keeps the last command forever)."""
        self.jog_pub.publish(conversions.make_joint_jog(
            self.joint_names, [0.0] * len(self.joint_names), self.get_clock().now().to_msg()))

    def publish_status(self, now, extra=None, level=None, message=None):
        """
        Publish the core's status on /controller/status (plus ``extra`` values).

        Never call it holding ``lock``: ``status_lock`` comes first, so that statuses go out in
        the order they were read, and the core's lock is not held while publishing.
        """
        with self.status_lock:
            with self.lock:
                status = self.core.status()
                self.last_status = now
            values = dict(status.values)
            values['goal_id'] = self.motion_goals.get(int(values.get('motion_id', 0)), '')
            values['max_tick_gap'] = f'{self.max_tick_gap:.4f}'
            values.update(extra or {})
            self.status_pub.publish(conversions.make_status(
                'controller', level or status.level, message or status.message, values))


def main(args=None):
    """
    Run the controller node until Ctrl-C, SIGTERM or shutdown; then send a zero command.

    rclpy's own signal handlers would shut the context down before the node could publish that
    zero (and the vendor driver keeps the last command forever); ``shutdown.run_node`` keeps the
    context valid until ``destroy_node()`` has sent it, and ignores any further signal meanwhile.
    """
    # The tick thread must get the interpreter promptly when its deadline comes, not after the
    # default 5 ms switch interval while the executor thread runs Python: this keeps the period
    # error p99 well under a millisecond at 100 Hz (bench/bench_controller.py).
    sys.setswitchinterval(0.0005)
    shutdown.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
