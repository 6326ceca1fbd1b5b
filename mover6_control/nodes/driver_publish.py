"""
The driver node's publisher thread: each cycle's report to /joint_states and /diagnostics.

The control thread never waits on DDS (a DDS write can block for hundreds of milliseconds, see
controller_node.py): ``on_cycle`` hands the cycle's report over and this thread publishes it.
/joint_states goes out every cycle once every module has answered; /diagnostics at
``diagnostics_rate`` and at once on every change (of a state, why the arm holds, the refused
JointJogs or the bad frames) and on every refused JointJog. Each change of the arm's state is
logged once, with why it holds.

``ReportPublisher`` is a part of ``driver_node.DriverNode`` (its state is the node's, set in
``DriverNode.__init__``); it is not used on its own.
"""

import re
from typing import Iterable, Optional

from diagnostic_msgs.msg import DiagnosticArray
from mover6_control.hardware.driver_state import ArmReport, ModuleState
from mover6_control.hardware.gripper import NAME as GRIPPER
from mover6_control.nodes.messages.conversions import make_joint_state, make_status

LEVELS = {ModuleState.FAULT: 'ERROR', ModuleState.ERROR: 'ERROR',
          ModuleState.DISCONNECTED: 'WARN', ModuleState.CONNECTED: 'WARN',
          ModuleState.ENABLED: 'OK', ModuleState.REFERENCED: 'OK',
          ModuleState.POWER_LOST: 'ERROR'}
"""The diagnostic level of a joint's, or the arm's, state."""


class ReportPublisher:
    """The publisher thread of ``DriverNode`` (module docstring)."""

    def on_cycle(self, report: ArmReport) -> None:
        """Take one cycle's report (control thread: hand it over, never wait on DDS)."""
        self._jog_pending = False
        with self._wake:
            self._latest = report
            self._wake.notify()

    def _notify(self):
        with self._wake:
            self._diag_now = True
            self._wake.notify()

    def _publish_loop(self):
        while True:
            with self._wake:
                while self._latest is None and not self._diag_now and not self._closing:
                    self._wake.wait(0.5)
                if self._closing:
                    return
                report, self._latest = self._latest, None
                force, self._diag_now = self._diag_now, False
            try:
                self._publish(report, force)
            except Exception as err:  # noqa: B902 - the next cycle's report is published again
                self.get_logger().error(f'publishing failed: {type(err).__name__}: {err}',
                                        throttle_duration_sec=1.0)

    def _publish(self, report: Optional[ArmReport], force: bool) -> None:
        """Publish one cycle's report (``None``: only /diagnostics, e.g. on a refusal)."""
        if not self._scheduling_logged and report is not None:
            self._scheduling_logged = True
            self.get_logger().info(f'cycle thread: {self.driver.scheduling}')
        if report is not None and (self._seen is None or
                                   report.state != self._seen.state or
                                   hold_kind(report.hold) != hold_kind(self._seen.hold)):
            # Each change of the arm's state is logged once, with why it holds.
            text = f'arm {report.state}' + (f': holds, {report.hold}' if report.hold else '')
            if report.state in (ModuleState.ERROR, ModuleState.FAULT, ModuleState.POWER_LOST):
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)
        if report is not None:
            self._seen = report
            if all(j.replies for j in report.joints):
                grip = report.gripper        # the gripper's estimated gap, as a joint
                self.pub_states.publish(make_joint_state(
                    self.names + (GRIPPER,), [j.q for j in report.joints] + [grip.position],
                    [j.qd for j in report.joints] + [grip.velocity],
                    stamp=self.get_clock().now().to_msg()))
        if self._seen is not None:
            self._maybe_diagnostics(self._seen, force)

    def _maybe_diagnostics(self, report, force=False):
        key = (report.state, report.hold, tuple(j.state for j in report.joints), self.refused,
               report.frames_bad)
        period = 1.0 / self.get_parameter('diagnostics_rate').value
        last = self._last_diag
        if not force and last is not None and last[0] == key and \
                report.time - last[1] < period:
            return
        self._last_diag = (key, report.time)
        msg = DiagnosticArray()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.status.append(make_status(
            'driver: bus', LEVELS[report.state], report.hold or f'arm {report.state}', {
                'state': report.state, 'hold': report.hold, 'cycle_period': report.period,
                'frames_dropped': report.frames_dropped, 'frames_bad': report.frames_bad,
                'tx_errors': report.tx_errors, 'bus_error': report.bus_error,
                'bad_frames': counts(report.bad_frames), 'last_bad_frame': report.last_bad_frame,
                'jog_received': self.jogs, 'jog_refused': self.refused,
                'jog_refused_by': counts(sorted(self.refused_by.items())),
                'jog_clipped': self.clipped, 'jog_superseded': self.superseded,
                'last_refusal': self.last_refusal, 'scheduling': self.driver.scheduling,
                'link': report.link, 'link_losses': report.link_losses,
                'link_outage': report.link_outage}))
        for j in report.joints:
            msg.status.append(make_status(
                f'driver: {j.name}', LEVELS[j.state], j.state, {
                    'state': j.state, 'flags': f'0x{j.flags:02X}',
                    'flag_names': ' '.join(j.flag_names), 'referenced': j.referenced,
                    'position': j.q, 'lag': j.lag, 'silent_cycles': j.silent_cycles}))
        self.pub_diag.publish(msg)


def hold_kind(hold: str) -> str:
    """Return why the arm holds without the counts that change every cycle."""
    return re.sub(r'\d+ cycles', 'N cycles', hold)


def counts(pairs: Iterable[tuple[str, int]]) -> str:
    """Return ``(name, count)`` pairs as one line, 'name count, ...' ('' for none)."""
    return ', '.join(f'{name} {count}' for name, count in pairs)
