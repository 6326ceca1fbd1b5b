"""
The sim_bridge node's physics thread: pace the steps, run them, publish what they produce.

``PhysicsThread`` runs the ``Simulator`` in its own thread, paced against the monotonic wall clock
at ``Pacing.rtf`` (0 = as fast as it can). It owns the locks the node's callbacks share with it:
``lock`` guards the simulator and the publication schedule, ``step_lock`` pacing and stepping
(here, or in a callback that first runs the steps due before it acts: ``catch_up``). Each step
publishes /clock (with ``publish_clock``) and, when due, /joint_states (``rest_period`` while the
arm rests) through its ``BridgeOutputs``; ~/contacts when the contacts changed; ~/status once a
second, with the refused /JointJog messages of the node's ``Rejections``.

Built from what it needs (the simulator, the ``Pacing``, the ``BridgeOutputs`` and the
``Rejections``), so a test can build one alone on a ``Simulator`` and outputs of its own;
``bridge_node.SimBridgeNode`` builds it with the node's publishers and logger.
"""

from dataclasses import dataclass
import math
import threading
import time
from typing import Any, Optional

from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.realtime import raise_this_thread, run_normal
from mover6_control.values import JogRequest
from sim_bridge.pacing import steps_due
from sim_bridge.simulator import JointReading, Simulator

MAX_BATCH = 200           # physics steps per loop pass before pacing gives up and re-anchors
VIEWER_PERIOD = 1.0 / 30.0
STATUS_PERIOD = 1.0       # [s] wall time between ~/status reports
STOP_WAIT = 5.0        # [s] longest wait for the thread at ``stop``


@dataclass
class Pacing:
    """
    How the physics runs and publishes; ``rtf`` and the two periods may change while it runs.

    ``dt`` [s] the physics step; ``rtf`` the real-time factor (0: as fast as it can);
    ``publish_period`` [s] of /joint_states (vendor mode: the driver's cycle); ``rest_period``
    [s] of /joint_states while the arm rests (at least ``publish_period``); ``vendor`` the
    simulator's vendor_driver mode (one reading per driver cycle); ``publish_clock`` a /clock
    after every step (and sim-time stamps); ``priority`` the SCHED_FIFO priority while paced.
    """

    dt: float
    rtf: float
    publish_period: float
    rest_period: float
    vendor: bool = False
    publish_clock: bool = False
    priority: int = 0


class Rejections:
    """The refused /JointJog messages: how many, and the last reason (in ~/status)."""

    def __init__(self):
        """Start with none."""
        self.count = 0
        self.last = ''

    def add(self, reason: str) -> None:
        """Count one refusal and keep its reason."""
        self.count += 1
        self.last = reason


class BridgeOutputs:
    """
    Where the bridge's products go: /joint_states, /clock, ~/status, ~/contacts and the log.

    ``joint_states`` takes serialized messages (``state_writer``'s bytes: the arm's joints, then
    the ``unfitted`` positions of the joints the simulation has not, at rest); ``clock`` is None
    without ``publish_clock``; ``node_clock`` stamps /joint_states unless ``sim_stamps`` (then a
    reading's sim time does).
    """

    def __init__(self, logger: Any, joint_states: Any, status: Any, contacts: Any,
                 clock: Optional[Any], state_writer: Any, node_clock: Any, sim_stamps: bool,
                 unfitted: tuple = ()):
        """Keep the publishers, the writer and the clock."""
        self.logger = logger
        self.joint_states = joint_states
        self.status = status
        self.contacts = contacts
        self.clock = clock
        self.state_writer = state_writer
        self.node_clock = node_clock
        self.sim_stamps = sim_stamps
        self.unfitted_q = [float(x) for x in unfitted]
        self.unfitted_zero = [0.0] * len(unfitted)

    def publish_state(self, reading: JointReading) -> None:
        """Publish a ``JointReading`` on /joint_states (sim time stamps with sim_stamps)."""
        if self.sim_stamps:
            stamp = conversions.seconds_to_stamp(reading.time)
            sec, nanosec = stamp.sec, stamp.nanosec
        else:
            sec, nanosec = divmod(now_ns(self.node_clock), 1_000_000_000)
        self.joint_states.publish(self.state_writer.serialize(
            sec, nanosec, reading.q.tolist() + self.unfitted_q,
            reading.qd.tolist() + self.unfitted_zero,
            reading.effort.tolist() + self.unfitted_zero))

    def publish_clock(self, t: float) -> None:
        """Publish /clock at sim time ``t`` [s] (nothing without a /clock publisher)."""
        if self.clock is not None:
            self.clock.publish(conversions.make_clock(t))


class PhysicsThread:
    """The bridge's physics in a thread of its own; see the module docstring."""

    def __init__(self, sim: Simulator, pacing: Pacing, outputs: BridgeOutputs,
                 rejections: Rejections):
        """Take the simulator, pacing, outputs and refusal count; ``start`` runs the thread."""
        self.sim = sim
        self.pacing = pacing
        self.out = outputs
        self.rejections = rejections
        self.viewer = None               # a passive MuJoCo viewer, synced while it runs
        self.lock = threading.Lock()
        self.step_lock = threading.Lock()    # pacing and stepping: this thread or a callback
        self.stop_event = threading.Event()
        self.wake = threading.Event()        # a command or a stop: the thread looks now
        self.reanchor = False            # real_time_factor changed: pace from now on
        self.anchor = None               # (wall, sim) time the pace counts from
        self.paused = False
        self.pending = None              # (command_count, wall arrival) awaiting its first step
        self.next_publish = sim.time     # [s] sim time of the next /joint_states
        self.latencies = []              # [s] JointJog arrival to the end of its first step
        self.overruns = 0                # times pacing fell behind and re-anchored
        self.failure = None              # why the thread stopped, if it did
        self._was_stale = True
        self._last_reading_time = None
        self._mujoco_warnings = {}
        self._contact_report = None      # (contact_steps, touching) last reported
        self._status_due = 0.0           # [s] monotonic: the next ~/status
        self._status_mark = None         # (wall, sim) time of the last ~/status
        self._priority = pacing.priority
        self._raised = False
        self.thread = threading.Thread(target=self._run, name='sim_bridge_physics', daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self.thread.start()

    def stop(self) -> None:
        """Stop the thread (waiting up to ``STOP_WAIT``) and close the viewer."""
        self.stop_event.set()
        self.wake.set()
        if self.thread.is_alive():
            self.thread.join(timeout=STOP_WAIT)
        if self.viewer is not None:
            self.viewer.close()
            self.viewer = None

    # --- live settings -----------------------------------------------------------------------

    def set_rtf(self, rtf: float) -> None:
        """Pace at ``rtf`` from now on (the pace re-anchors at the present time)."""
        self.pacing.rtf = rtf
        self.reanchor = True
        self.wake.set()

    def set_periods(self, publish_period: Optional[float] = None,
                    rest_period: Optional[float] = None) -> None:
        """
        Publish /joint_states every ``publish_period`` [s] (``rest_period`` at rest) from now.

        The next one comes at most one new period of sim time after the change.
        """
        self.wake.set()
        with self.lock:
            if publish_period is not None:
                self.pacing.publish_period = publish_period
            if rest_period is not None:
                self.pacing.rest_period = rest_period
            self.next_publish = min(self.next_publish, self.sim.time + self.pacing.publish_period)

    # --- commands ----------------------------------------------------------------------------

    def command(self, jog: JogRequest, arrival: float) -> list:
        """
        Hand a checked command to the simulator after the steps due before it; return warnings.

        ``arrival`` [s] monotonic: its latency is measured to the end of its first step. A
        resting arm's slower /joint_states: the full rate from this command on.
        """
        with self.step_lock:
            self.catch_up()              # the steps due before it came: the command before
            with self.lock:
                warnings = self.sim.take_jog(jog, self.sim.time)
                self.pending = (self.sim.command_count, arrival)
                self.next_publish = min(self.next_publish,
                                        self.sim.time + self.pacing.publish_period)
        self.wake.set()                  # its first step when due, not at the next publication
        return warnings

    def refresh(self, arrival: float) -> bool:
        """
        Restart the held command's timeout at ``arrival`` (monotonic [s]); False: not possible.

        The command counts as received at the sim time ``catch_up`` would reach now, so the
        steps before it run with the command before (the same velocities, not yet stale) and
        the ones after with the timeout restarted, exactly as after a new command. Not while
        paused, unpaced, about to re-anchor, behind by a whole batch, in vendor_driver mode or
        when the held command would be stale by then: the caller takes it as a new command.
        """
        p = self.pacing
        with self.step_lock:
            anchor, rtf = self.anchor, p.rtf
            if p.vendor or self.paused or anchor is None or not rtf > 0.0 or self.reanchor:
                return False
            with self.lock:
                t = self.sim.time
                n = steps_due(t - anchor[1], arrival - anchor[0], rtf, p.dt, MAX_BATCH)
                if n >= MAX_BATCH:
                    return False
                return self.sim.refresh_command(t + n * p.dt)

    # --- the thread --------------------------------------------------------------------------

    def _run(self):
        """Run the physics loop; a failure is logged loudly, never lost in a thread."""
        try:
            self._keep_priority()
            self._loop()
        except Exception as exc:  # noqa: B902 - report whatever stopped the physics
            self.failure = f'{type(exc).__name__}: {exc}'
            self.out.logger.fatal(f'physics thread stopped: {self.failure}')

    def _keep_priority(self):
        """
        Run this thread at SCHED_FIFO ``priority`` while paced, the rest just below.

        ``mover6_control.realtime.raise_this_thread``, as the controller's tick and the driver's
        cycle: under load the simulated arm keeps its pace as a real one does; 0: as is.
        Unpaced (``rtf`` 0, as fast as it can, which may be set live) the thread never sleeps,
        so it runs at normal scheduling then. A refusal is said once and not tried again.
        """
        want = self._priority > 0 and self.pacing.rtf > 0.0
        if want == self._raised:
            return
        if want:
            self._raised = raise_this_thread(self._priority, self.out.logger, 'physics',
                                             'physics_priority')
            if not self._raised:
                self._priority = 0
        else:
            run_normal()
            self._raised = False
            self.out.logger.info('physics thread at normal scheduling while unpaced '
                                 '(real_time_factor 0)')

    def _loop(self):
        """
        Step, publish and pace until stopped; re-anchor after a pause or an overrun.

        The thread wakes when a step is due that matters outside: the one a /joint_states
        publication comes after, or the first step of a new command (``command`` wakes the
        thread); the steps between run in the same round, at most one publication period late
        in wall time but each with the command it had before (a command first runs the steps
        due before it came). Waking for every 2 ms step cost more CPU than the steps. With
        ``publish_clock`` (a /clock after every step: sim-time nodes wait on it) and in
        vendor_driver mode every step is a wake-up.
        """
        last_view = 0.0
        while not self.stop_event.is_set():
            self._keep_priority()
            self.wake.clear()
            if time.monotonic() >= self._status_due:
                self.report_status(time.monotonic())
            if self.paused:
                with self.step_lock:
                    self.anchor = None
                self.wake.wait(0.005)
                continue
            with self.step_lock:
                overran = self.catch_up()
                due = self._next_wake()
            now = time.monotonic()
            if self.viewer is not None and now - last_view > VIEWER_PERIOD:
                last_view = now
                self._sync_viewer()
            if overran and self._raised:
                time.sleep(self.pacing.publish_period)   # behind at real-time priority: rest
            elif due is None:
                time.sleep(0)            # let the callbacks in
            elif due > now:
                self.wake.wait(due - now)

    def catch_up(self) -> bool:
        """
        Run the physics steps due by now at the pace in force (hold ``step_lock``).

        Return whether it overran: paced, a whole batch due (the pace re-anchors).
        """
        if self.paused:
            self.anchor = None
            return False
        now = time.monotonic()
        rtf = self.pacing.rtf            # read once per round: it may be set live
        if self.reanchor:
            self.reanchor, self.anchor = False, None
        if self.anchor is None:
            self.anchor = (now, self.sim.time)
        n = steps_due(self.sim.time - self.anchor[1], now - self.anchor[0], rtf, self.pacing.dt,
                      MAX_BATCH)
        for _ in range(n):
            self.one_step()
        if rtf > 0.0 and n == MAX_BATCH:
            self.overruns += 1
            self.anchor = None
            return True
        return False

    def _next_wake(self):
        """Return the wall time [s] the next step that matters is due; None: now (step_lock)."""
        p = self.pacing
        rtf, anchor = p.rtf, self.anchor
        if not rtf > 0.0 or anchor is None or self.reanchor:
            return None
        steps = 1
        if self.pending is None and not (p.vendor or p.publish_clock):
            with self.lock:
                ahead = self.next_publish - self.sim.time
            steps = max(1, math.ceil(ahead / p.dt - 1e-6))
        return anchor[0] + (self.sim.time + steps * p.dt - anchor[1]) / rtf

    def one_step(self, publish_states: bool = True) -> None:
        """Advance one physics step; publish /clock and, when due, /joint_states."""
        p = self.pacing
        with self.lock:
            self.sim.step()
            t = self.sim.time
            pending = self.pending
            if pending is not None and self.sim.applied_count >= pending[0]:
                self.latencies.append(time.monotonic() - pending[1])
                del self.latencies[:-1000]
                self.pending = None
            stale = self.sim.is_stale()
            reading = None
            if p.vendor:
                candidate = self.sim.state()
                if candidate.time != self._last_reading_time:
                    reading = candidate
                    self._last_reading_time = candidate.time
            elif t >= self.next_publish - 1e-9:
                reading = self.sim.state()
                period = p.publish_period
                if p.rest_period > period and self.sim.at_rest():
                    period = p.rest_period
                self.next_publish += period
                if self.next_publish <= t:
                    self.next_publish = t + p.publish_period
        if stale and not self._was_stale:
            self.out.logger.info('/JointJog command stale: joints halted')
        self._was_stale = stale
        if reading is not None:
            self._check_physics()
        self.out.publish_clock(t)
        if reading is not None and publish_states:
            self.out.publish_state(reading)

    def report_status(self, now: float) -> None:
        """
        Publish ~/status: sim time, the real-time factor since the last report, the rates.

        Once a second of wall time (``now``, monotonic [s]). ``real_time_factor`` is sim time
        over monotonic wall time between the last two reports (``sim_time`` and ``wall_time``
        say what it came from), ``joint_states_rate`` the rate in force now
        (``rest_publish_rate`` while the arm rests).
        """
        p = self.pacing
        self._status_due = now + STATUS_PERIOD
        with self.lock:
            sim_time, resting = self.sim.time, self.sim.at_rest()
        mark, self._status_mark = self._status_mark, (now, sim_time)
        measured = ((sim_time - mark[1]) / (now - mark[0])
                    if mark is not None and now > mark[0] else float('nan'))
        if p.vendor:
            period = p.publish_period
        else:
            period = max(p.rest_period, p.publish_period) if resting else p.publish_period
        values = {'sim_time': f'{sim_time:.6f}', 'wall_time': f'{now:.6f}',
                  'real_time_factor': f'{measured:.4f}', 'real_time_factor_target': p.rtf,
                  'joint_states_rate': f'{1.0 / period:g}', 'at_rest': str(resting).lower(),
                  'overruns': self.overruns, 'jog_rejected': self.rejections.count,
                  'last_rejection': self.rejections.last}
        text = (f'paused at t = {sim_time:.3f} s' if self.paused else
                f'running at real-time factor {measured:.3f}')
        self.out.status.publish(conversions.make_status('sim_bridge', 'OK', text, values))

    def _check_physics(self):
        """Log an error when MuJoCo reports a new warning (a blow-up resets its state)."""
        with self.lock:
            warnings = self.sim.warnings()
        new = {k: n for k, n in warnings.items() if n > self._mujoco_warnings.get(k, 0)}
        self._mujoco_warnings = warnings
        if new:
            self.out.logger.error(f'MuJoCo warnings {new}: the physics was reset by MuJoCo')
        self._report_contacts()

    def _report_contacts(self):
        """Publish ~/contacts when the contact count or the shapes touching changed."""
        with self.lock:
            steps, first = self.sim.contact_steps, self.sim.first_contact
            touching = ', '.join(sorted(f'{a}-{b}' for a, b in self.sim.contacts()))
        if (steps, touching) == self._contact_report:
            return
        self._contact_report = (steps, touching)
        values = {'contact_steps': steps, 'touching': touching}
        if first is None:
            self.out.contacts.publish(conversions.make_status(
                'sim_bridge contacts', 'OK', 'no contact since the last reset', values))
            return
        t, shapes, depth = first
        values.update(first_contact_time=f'{t:.3f}', first_contact='-'.join(shapes),
                      first_contact_depth=f'{depth:.4f}')
        text = f'{" and ".join(shapes)} touched at {t:.3f} s ({depth * 1e3:.1f} mm deep)'
        self.out.logger.warning(f'contact: {text}', throttle_duration_sec=2.0)
        self.out.contacts.publish(conversions.make_status('sim_bridge contacts', 'WARN', text,
                                                          values))

    def _sync_viewer(self):
        """Show the current state in the viewer (closed viewer: stop syncing)."""
        if not self.viewer.is_running():
            self.viewer = None
            return
        with self.lock:
            self.viewer.sync()
