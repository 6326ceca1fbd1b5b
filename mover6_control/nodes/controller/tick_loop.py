"""
The controller node's tick thread: one core tick, one /JointJog and the status when due.

The tick runs in its own thread that sleeps on the node's clock (``node_clock.sleep_until_ns``:
on the system clock a timed wait, on sim time ``Clock.sleep_until``): that costs less CPU and
jitter than an executor timer; the executor thread serves the callbacks, and the node's lock
keeps the core consistent between the two (``core.state``, ``core.config`` and the core's other
state are read only under it). Nothing slow happens under that lock. JointJog and status are
published outside it: a DDS write can block. Measured (``bench/bench_churn.py``): Fast DDS 2.14
holds one send lock per participant, and its discovery thread holds it while it opens the
shared-memory port of a process that just joined the graph, which can take 333 ms
(eProsima/Fast-DDS#6535); every write of the node waits that long.

The status value ``max_tick_gap`` [s] is the longest time between two ticks since the node
started (node clock; nominal ``1 / rate``), and a tick later than ``TICK_GAP_WARN`` logs a
warning, so a stalled tick thread shows in the controller and not only as a stale command at the
driver. To see what held it up, set the environment variable ``MOVER6_TICK_WATCHDOG`` to a time
[s]: a tick later than that dumps the stack of every thread to stderr (``faulthandler``, which
needs no interpreter lock for it; wall time, so a paused sim clock trips it too). The status
value ``max_states_age`` [s] (both in ``tick_figures``) is the age of the oldest valid
/joint_states a tick found (node clock; nominal the states' period plus a tick): how long their
intake was held up at most (``state_timeout`` faults).

The tick never dies: an exception inside it is a fault (zero command, the reason on the
status, cleared by fresh joint states as any fault); when ``MAX_TICK_FAILURES`` ticks in a row
raise, or the tick thread ends by an exception, the node gives up (``fatal``) and its process
exits with 1 after the last zero command, so the launcher sees it.

``TickLoop`` gets what it uses in its constructor: the core and its lock, the node clock, the
/JointJog output, the status, the tick's figures and the event that says the core has valid
states (the demand thread waits on it).
"""

import faulthandler
import os
import threading
import time
import traceback

from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.state_machine import FAULT
from mover6_control.nodes.controller.demand_thread import WAIT_FOR_STATES
from mover6_control.nodes.controller.jog_output import JogOutput
from mover6_control.nodes.controller.status_publisher import StatusPublisher
from mover6_control.nodes.controller.tick_figures import TickFigures
from mover6_control.nodes.runtime.node_clock import now_ns, sleep_until_ns
from mover6_control.realtime import raise_this_thread
from rclpy.clock import Clock
from rclpy.context import Context
from rclpy.impl.rcutils_logger import RcutilsLogger

# A tick this late [s] is logged: the driver (and the sim bridge) halt after 0.2 s without one.
TICK_GAP_WARN = 0.05
WATCHDOG_ENV = 'MOVER6_TICK_WATCHDOG'
# A tick that is due already when the one before ends still waits this fraction of a period
# (wall time) first: at real-time priority (tick_priority) a thread that never sleeps would take
# a whole CPU from every normal process.
TICK_REST = 0.1
# Ticks in a row that raised (each a fault with a zero command) after which the tick cannot run
# at all: the node gives up and its process exits with 1, so the launcher sees it.
MAX_TICK_FAILURES = 10


class TickLoop:
    """The controller's tick thread (module docstring)."""

    def __init__(self, core: ControllerCore, lock: threading.RLock, clock: Clock,
                 context: Context, logger: RcutilsLogger, jog: JogOutput,
                 status: StatusPublisher, figures: TickFigures, has_states: threading.Event,
                 priority: int):
        """Tick ``core`` (under ``lock``) on ``clock`` at real-time ``priority``; see ``start``."""
        self.core = core
        self.lock = lock
        self.clock = clock
        self.context = context
        self.logger = logger
        self.jog = jog
        self.status = status
        self.figures = figures
        self.has_states = has_states     # set while the core has valid states
        self.priority = priority
        self.running = True
        self.fatal = None                # why the tick cannot run: the process exits with 1
        self.tick_errors = 0             # ticks in a row that raised outside the core
        self.last_state = None           # the core's state after the latest tick
        self.pending_logged = False      # 'applies to the next motion' said, not yet applied
        self.thread = threading.Thread(target=self.run_ticks, name='controller_tick',
                                       daemon=True)

    def start(self) -> None:
        """Start the tick thread."""
        self.thread.start()

    def close(self, timeout: float) -> None:
        """Stop ticking; wait up to ``timeout`` [s] for the thread to end."""
        self.running = False
        if self.thread.is_alive() and self.thread is not threading.current_thread():
            self.thread.join(timeout=timeout)

    def note_pending(self, pending: bool) -> None:
        """Say whether parameters just set wait for the motion to end (logged when applied)."""
        with self.lock:
            self.pending_logged = pending

    def tick_loop(self) -> None:
        """
        Call ``on_tick`` every ``1 / rate`` [s] of the node's clock until the loop closes.

        The thread sleeps before every tick, at least ``TICK_REST`` of a period when it is late.
        Times are integer nanoseconds of the node clock (``node_clock``: no rclpy ``Time`` or
        ``Duration`` per tick; sim time sleeps in ``Clock.sleep_until``).
        """
        raise_this_thread(self.priority, self.logger, 'tick', 'tick_priority')
        clock = self.clock
        deadline = now_ns(clock)
        watchdog = float(os.environ.get(WATCHDOG_ENV) or 0.0)
        while self.running and self.context.ok():
            with self.lock:
                period = 1.0 / self.core.config.rate  # the rate in force: set live
            step = round(period * 1e9)
            if watchdog > 0.0:
                faulthandler.dump_traceback_later(watchdog + period)   # re-armed each tick
            deadline += step
            if now_ns(clock) >= deadline:       # late: rest all the same (real-time priority)
                time.sleep(period * TICK_REST)
            if not sleep_until_ns(clock, deadline, self.context):
                deadline = now_ns(clock)        # clock switched (sim time) or shutting down
                self.figures.forget_last_tick()   # no gap across the switch
                continue
            now = now_ns(clock)
            if now - deadline > step:
                deadline = now                  # fell behind by a whole period: no burst
            if self.running:
                self.run_tick()
        if watchdog > 0.0:
            faulthandler.cancel_dump_traceback_later()

    def run_ticks(self) -> None:
        """Run ``tick_loop`` (the tick thread); if it ends by an exception the node gives up."""
        try:
            self.tick_loop()
        except Exception as err:  # noqa: B902 - a dead tick thread must not go unnoticed
            self.give_up(f'the tick thread died: {type(err).__name__}: {err}',
                         traceback.format_exc())

    def run_tick(self) -> None:
        """
        Run ``on_tick``; a tick that raised is a fault, ``MAX_TICK_FAILURES`` in a row fatal.

        The core turns an exception in its tick into a fault itself (zero command, the reason
        on the status) and counts them; one here (publishing, the status) sends a zero command.
        """
        try:
            self.on_tick()
        except Exception as err:  # noqa: B902 - the tick goes on, the arm held
            self.tick_errors += 1
            self.logger.error(f'tick failed: {type(err).__name__}: {err}',
                              throttle_duration_sec=1.0)
            try:
                self.jog.send_zero()
            except Exception:  # noqa: B902 - giving up below if this keeps happening
                pass
        else:
            self.tick_errors = 0
        with self.lock:
            failures = self.core.tick_failures
            last = self.core.status().message if failures >= MAX_TICK_FAILURES else ''
        if failures >= MAX_TICK_FAILURES:
            self.give_up(f'{failures} ticks in a row failed ({last})')
        elif self.tick_errors >= MAX_TICK_FAILURES:
            self.give_up(f'{self.tick_errors} ticks in a row failed to publish')

    def give_up(self, reason: str, details: str = '') -> None:
        """Stop ticking for good: log ``reason``, send a zero command, let the process exit 1."""
        self.fatal = reason
        self.running = False
        log = f'{reason}; the controller stops'
        self.logger.fatal(f'{log}\n{details}' if details else log)
        try:
            self.jog.send_zero()
        except Exception:  # noqa: B902 - destroy_node sends one more
            pass

    def on_tick(self) -> None:
        """Run one control tick: publish the JointJog, and the status when due."""
        stamp_ns = now_ns(self.clock)
        now = stamp_ns * 1e-9
        gap = self.figures.note_tick(stamp_ns)
        with self.lock:
            t_states = self.core.robot.t_states     # of the latest valid states (None: none)
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
            profile, rate = self.core.config.law.profile, self.core.config.rate
            status_due = out.status_changed or self.status.due(now)
        if t_states is not None:
            self.figures.note_states_age(now - t_states)
        if applied:
            self.logger.info(f'parameters in force from now: {profile} at {rate:g} Hz')
        if fault_change is not None:        # entering fault and leaving it: logged once each
            if out.state == FAULT:
                self.logger.error(f'fault: {fault_change}')
            else:
                self.logger.info(f'fault cleared ({out.state}): {fault_change}')
        # Published without the lock: a DDS write can block (seen for 0.33 s right after start-up
        # while the sim bridge was being matched), and the callbacks must not wait for it.
        self.jog.publish(stamp_ns, out.jog)
        if gap > TICK_GAP_WARN:         # logged after the command went, not before it
            self.logger.warning(
                f'tick {gap * 1e3:.0f} ms after the one before (period '
                f'{1e3 / rate:.0f} ms): the tick thread stalled',
                throttle_duration_sec=1.0)
        if status_due:
            self.status.publish(now)
