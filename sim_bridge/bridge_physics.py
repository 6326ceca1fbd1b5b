"""
The sim_bridge node's physics thread: pace the steps, run them, publish what they produce.

Physics runs in its own thread, paced against the monotonic wall clock at the node's
``real_time_factor`` (0 = as fast as it can); the callbacks and this thread share the
``Simulator`` under the node's ``lock``, and pacing and stepping (here, or in a callback that
runs the steps due before it acts) under its ``step_lock``. Each step publishes /clock (with
``publish_clock``) and, when due, /joint_states (``rest_publish_rate`` while the arm rests);
~/contacts when the contacts changed; ~/status once a second.

``PhysicsLoop`` is a part of ``bridge_node.SimBridgeNode`` (its state is the node's, set in
``SimBridgeNode.__init__``); it is not used on its own.
"""

import math
import time

from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.realtime import raise_this_thread, run_normal
from sim_bridge.pacing import steps_due

MAX_BATCH = 200           # physics steps per loop pass before pacing gives up and re-anchors
VIEWER_PERIOD = 1.0 / 30.0
STATUS_PERIOD = 1.0       # [s] wall time between ~/status reports


class PhysicsLoop:
    """The physics thread of ``SimBridgeNode``; see the module docstring."""

    def _run(self):
        """Run the physics loop; a failure is logged loudly, never lost in a thread."""
        self._priority = self.get_parameter('physics_priority').value
        self._raised = False
        try:
            self._keep_priority()
            self._loop()
        except Exception as exc:  # noqa: B902 - report whatever stopped the physics
            self.failure = f'{type(exc).__name__}: {exc}'
            self.get_logger().fatal(f'physics thread stopped: {self.failure}')

    def _keep_priority(self):
        """
        Run this thread at SCHED_FIFO ``physics_priority`` while paced, the rest just below.

        ``mover6_control.realtime.raise_this_thread``, as the controller's tick and the driver's
        cycle: under load the simulated arm keeps its pace as a real one does; 0: as is.
        Unpaced (``real_time_factor`` 0, as fast as it can, which may be set live) the thread
        never sleeps, so it runs at normal scheduling then. A refusal is said once and not
        tried again.
        """
        want = self._priority > 0 and self.rtf > 0.0
        if want == self._raised:
            return
        if want:
            self._raised = raise_this_thread(self._priority, self.get_logger(), 'physics',
                                             'physics_priority')
            if not self._raised:
                self._priority = 0
        else:
            run_normal()
            self._raised = False
            self.get_logger().info('physics thread at normal scheduling while unpaced '
                                   '(real_time_factor 0)')

    def _loop(self):
        """
        Step, publish and pace until stopped; re-anchor after a pause or an overrun.

        The thread wakes when a step is due that matters outside: the one a /joint_states
        publication comes after, or the first step of a new command (its callback wakes the
        thread); the steps between run in the same round, at most one publication period late
        in wall time but each with the command it had before (a command's callback first runs
        the steps due before it came). Waking for every 2 ms step cost more CPU than the steps.
        With ``publish_clock`` (a /clock after every step: sim-time nodes wait on it) and in
        vendor_driver mode every step is a wake-up, as before.
        """
        last_view = 0.0
        while not self.stop_event.is_set():
            self._keep_priority()
            self._wake.clear()
            if time.monotonic() >= self._status_due:
                self._report_status(time.monotonic())
            if self.paused:
                with self.step_lock:
                    self._anchor = None
                self._wake.wait(0.005)
                continue
            with self.step_lock:
                overran = self._catch_up()
                due = self._next_wake()
            now = time.monotonic()
            if self.viewer is not None and now - last_view > VIEWER_PERIOD:
                last_view = now
                self._sync_viewer()
            if overran and self._raised:
                time.sleep(self.publish_period)   # behind at real-time priority: rest all the same
            elif due is None:
                time.sleep(0)            # let the callbacks in
            elif due > now:
                self._wake.wait(due - now)

    def _catch_up(self):
        """
        Run the physics steps due by now at the pace in force (hold ``step_lock``).

        Return whether it overran: paced, a whole batch due (the pace re-anchors).
        """
        if self.paused:
            self._anchor = None
            return False
        now = time.monotonic()
        rtf = self.rtf                   # read once per round: it may be set live
        if self._reanchor:
            self._reanchor, self._anchor = False, None
        if self._anchor is None:
            self._anchor = (now, self.sim.time)
        n = steps_due(self.sim.time - self._anchor[1], now - self._anchor[0], rtf, self.dt,
                      MAX_BATCH)
        for _ in range(n):
            self._one_step()
        if rtf > 0.0 and n == MAX_BATCH:
            self.overruns += 1
            self._anchor = None
            return True
        return False

    def _next_wake(self):
        """Return the wall time [s] the next step that matters is due; None: now (step_lock)."""
        rtf, anchor = self.rtf, self._anchor
        if not rtf > 0.0 or anchor is None or self._reanchor:
            return None
        steps = 1
        if self._pending is None and not (self.vendor or self.publish_clock):
            with self.lock:
                ahead = self._next_publish - self.sim.time
            steps = max(1, math.ceil(ahead / self.dt - 1e-6))
        return anchor[0] + (self.sim.time + steps * self.dt - anchor[1]) / rtf

    def _one_step(self, publish_states=True):
        """Advance one physics step; publish /clock and, when due, /joint_states."""
        with self.lock:
            self.sim.step()
            t = self.sim.time
            pending = self._pending
            if pending is not None and self.sim.applied_count >= pending[0]:
                self.latencies.append(time.monotonic() - pending[1])
                del self.latencies[:-1000]
                self._pending = None
            stale = self.sim.is_stale()
            reading = None
            if self.vendor:
                candidate = self.sim.state()
                if candidate.time != self._last_reading_time:
                    reading = candidate
                    self._last_reading_time = candidate.time
            elif t >= self._next_publish - 1e-9:
                reading = self.sim.state()
                period = self.publish_period
                if self.rest_period > period and self.sim.at_rest():
                    period = self.rest_period
                self._next_publish += period
                if self._next_publish <= t:
                    self._next_publish = t + self.publish_period
        if stale and not self._was_stale:
            self.get_logger().info('/JointJog command stale: joints halted')
        self._was_stale = stale
        if reading is not None:
            self._check_physics()
        if self.clock_pub is not None:
            self.clock_pub.publish(conversions.make_clock(t))
        if reading is not None and publish_states:
            self._publish_state(reading)

    def _report_status(self, now):
        """
        Publish ~/status: sim time, the real-time factor since the last report, the rates.

        Once a second of wall time. ``real_time_factor`` is sim time over monotonic wall time
        between the last two reports (``sim_time`` and ``wall_time`` say what it came from),
        ``joint_states_rate`` the rate in force now (``rest_publish_rate`` while the arm
        rests).
        """
        self._status_due = now + STATUS_PERIOD
        with self.lock:
            sim_time, resting = self.sim.time, self.sim.at_rest()
        mark, self._status_mark = self._status_mark, (now, sim_time)
        measured = ((sim_time - mark[1]) / (now - mark[0])
                    if mark is not None and now > mark[0] else float('nan'))
        if self.vendor:
            period = self.publish_period
        else:
            period = max(self.rest_period, self.publish_period) if resting else self.publish_period
        values = {'sim_time': f'{sim_time:.6f}', 'wall_time': f'{now:.6f}',
                  'real_time_factor': f'{measured:.4f}', 'real_time_factor_target': self.rtf,
                  'joint_states_rate': f'{1.0 / period:g}', 'at_rest': str(resting).lower(),
                  'overruns': self.overruns, 'jog_rejected': self.rejected,
                  'last_rejection': self.last_rejection}
        text = (f'paused at t = {sim_time:.3f} s' if self.paused else
                f'running at real-time factor {measured:.3f}')
        self.status_pub.publish(conversions.make_status('sim_bridge', 'OK', text, values))

    def _check_physics(self):
        """Log an error when MuJoCo reports a new warning (a blow-up resets its state)."""
        with self.lock:
            warnings = self.sim.warnings()
        new = {k: n for k, n in warnings.items() if n > self._mujoco_warnings.get(k, 0)}
        self._mujoco_warnings = warnings
        if new:
            self.get_logger().error(f'MuJoCo warnings {new}: the physics was reset by MuJoCo')
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
            self.contacts_pub.publish(conversions.make_status(
                'sim_bridge contacts', 'OK', 'no contact since the last reset', values))
            return
        t, shapes, depth = first
        values.update(first_contact_time=f'{t:.3f}', first_contact='-'.join(shapes),
                      first_contact_depth=f'{depth:.4f}')
        text = f'{" and ".join(shapes)} touched at {t:.3f} s ({depth * 1e3:.1f} mm deep)'
        self.get_logger().warning(f'contact: {text}', throttle_duration_sec=2.0)
        self.contacts_pub.publish(conversions.make_status('sim_bridge contacts', 'WARN', text,
                                                          values))

    def _refresh(self, arrival):
        """
        Restart the held command's timeout at ``arrival`` (monotonic [s]); False: not possible.

        The command counts as received at the sim time ``_catch_up`` would reach now, so the
        steps before it run with the command before (the same velocities, not yet stale) and
        the ones after with the timeout restarted, exactly as after a new command. Not while
        paused, unpaced, about to re-anchor, behind by a whole batch, in vendor_driver mode or
        when the held command would be stale by then: the caller takes it as a new command.
        """
        with self.step_lock:
            anchor, rtf = self._anchor, self.rtf
            if (self.vendor or self.paused or anchor is None or not rtf > 0.0
                    or self._reanchor):
                return False
            with self.lock:
                t = self.sim.time
                n = steps_due(t - anchor[1], arrival - anchor[0], rtf, self.dt, MAX_BATCH)
                if n >= MAX_BATCH:
                    return False
                return self.sim.refresh_command(t + n * self.dt)

    def _publish_state(self, reading):
        """Publish a ``JointReading`` on /joint_states (sim time stamps with publish_clock)."""
        if self.publish_clock:
            stamp = conversions.seconds_to_stamp(reading.time)
            sec, nanosec = stamp.sec, stamp.nanosec
        else:
            sec, nanosec = divmod(now_ns(self.get_clock()), 1_000_000_000)
        self.joint_states_pub.publish(self._state_writer.serialize(
            sec, nanosec, reading.q.tolist(), reading.qd.tolist(), reading.effort.tolist()))

    def _sync_viewer(self):
        """Show the current state in the viewer (closed viewer: stop syncing)."""
        if not self.viewer.is_running():
            self.viewer = None
            return
        with self.lock:
            self.viewer.sync()
