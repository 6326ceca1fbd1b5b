"""
The driver's publisher thread: each cycle's report to /joint_states and /diagnostics.

The control thread never waits on DDS (a DDS write can block for hundreds of milliseconds):
``on_cycle`` hands the cycle's report over and this thread publishes it. /joint_states goes out
every cycle once every module has answered; /diagnostics at ``diagnostics_rate`` and at once on
every change (of a state, the lifecycle state, why the arm holds, the refused JointJogs or the
bad frames) and on every refused JointJog. Each change of the arm's state is logged once, with
why it holds. The bus status carries the lifecycle state (``lifecycle``); when power is lost on
every module its message is the arm's hold reason: "power lost (e-stop?)" and the recovery steps.
"""

import re
import threading
from typing import Callable, Iterable, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from mover6_control.hardware.driver_state import ArmReport, ModuleState
from mover6_control.hardware.gripper import NAME as GRIPPER
from mover6_control.nodes.driver.jog_intake import JogCounts
from mover6_control.nodes.messages.conversions import make_joint_state, make_status
from sensor_msgs.msg import JointState

# The name of the bus's status on /diagnostics; each joint's is 'driver: <joint>'.
BUS_STATUS = 'driver: bus'

LEVELS = {ModuleState.FAULT: 'ERROR', ModuleState.ERROR: 'ERROR',
          ModuleState.DISCONNECTED: 'WARN', ModuleState.CONNECTED: 'WARN',
          ModuleState.ENABLED: 'OK', ModuleState.REFERENCED: 'OK',
          ModuleState.POWER_LOST: 'ERROR'}
"""The diagnostic level of a joint's, or the arm's, state."""


class ReportPublisher:
    """
    Publish the driver's reports from a thread of its own (module docstring).

    ``node`` gives the publishers, clock and logger; ``names`` are the joints'; ``counts`` the
    JointJog intake's; ``lifecycle()`` the node's lifecycle state; ``scheduling()`` what the
    control thread got; ``rate()`` the live ``diagnostics_rate`` [Hz].
    """

    def __init__(self, node, names: Sequence[str], counts: JogCounts,
                 lifecycle: Callable[[], str], scheduling: Callable[[], str],
                 rate: Callable[[], float]) -> None:
        self.node = node
        self.names = tuple(names)
        self.counts = counts
        self.lifecycle = lifecycle
        self.scheduling = scheduling
        self.rate = rate
        self.pub_states = node.create_publisher(JointState, 'joint_states', 10)
        self.pub_diag = node.create_publisher(DiagnosticArray, 'diagnostics', 10)
        self._latest = None
        self._seen = None
        self._last_diag = None
        self._diag_now = False
        self._scheduling_logged = False
        self._closing = False
        self._wake = threading.Condition()
        self._thread = threading.Thread(target=self._loop, name='driver_publish', daemon=True)
        self._thread.start()

    def on_cycle(self, report: ArmReport) -> None:
        """Take one cycle's report (control thread: hand it over, never wait on DDS)."""
        self.counts.taken_by_cycle()
        with self._wake:
            self._latest = report
            self._wake.notify()

    def notify(self) -> None:
        """Publish /diagnostics at once (a refusal, a lifecycle transition)."""
        with self._wake:
            self._diag_now = True
            self._wake.notify()

    def close(self) -> None:
        """Stop the thread."""
        with self._wake:
            self._closing = True
            self._wake.notify()
        self._thread.join(timeout=5.0)

    def _loop(self):
        while True:
            with self._wake:
                while self._latest is None and not self._diag_now and not self._closing:
                    self._wake.wait(0.5)
                if self._closing:
                    return
                report, self._latest = self._latest, None
                force, self._diag_now = self._diag_now, False
            try:
                self.publish(report, force)
            except Exception as err:  # noqa: B902 - the next cycle's report is published again
                self.node.get_logger().error(f'publishing failed: {type(err).__name__}: {err}',
                                             throttle_duration_sec=1.0)

    def publish(self, report: Optional[ArmReport], force: bool) -> None:
        """Publish one cycle's report (``None``: only /diagnostics, e.g. on a refusal)."""
        logger = self.node.get_logger()
        if not self._scheduling_logged and report is not None:
            self._scheduling_logged = True
            logger.info(f'cycle thread: {self.scheduling()}')
        if report is not None and (self._seen is None or
                                   report.state != self._seen.state or
                                   hold_kind(report.hold) != hold_kind(self._seen.hold)):
            # Each change of the arm's state is logged once, with why it holds.
            text = f'arm {report.state}' + (f': holds, {report.hold}' if report.hold else '')
            if report.state in (ModuleState.ERROR, ModuleState.FAULT, ModuleState.POWER_LOST):
                logger.warning(text)
            else:
                logger.info(text)
        if report is not None:
            self._seen = report
            if all(j.replies for j in report.joints):
                grip = report.gripper        # the gripper's estimated gap, as a joint
                self.pub_states.publish(make_joint_state(
                    self.names + (GRIPPER,), [j.q for j in report.joints] + [grip.position],
                    [j.qd for j in report.joints] + [grip.velocity],
                    stamp=self.node.get_clock().now().to_msg()))
        if self._seen is not None:
            self._maybe_diagnostics(self._seen, force)

    def _maybe_diagnostics(self, report, force=False):
        counts = self.counts
        lifecycle = self.lifecycle()
        key = (report.state, report.hold, tuple((j.state, j.reference_lost)
                                                for j in report.joints),
               counts.refused, report.frames_bad, lifecycle)
        period = 1.0 / self.rate()
        last = self._last_diag
        if not force and last is not None and last[0] == key and \
                report.time - last[1] < period:
            return
        self._last_diag = (key, report.time)
        msg = DiagnosticArray()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.status.append(make_status(
            BUS_STATUS, LEVELS[report.state], report.hold or f'arm {report.state}', {
                'state': report.state, 'lifecycle': lifecycle, 'hold': report.hold,
                'cycle_period': report.period,
                'frames_dropped': report.frames_dropped, 'frames_bad': report.frames_bad,
                'tx_errors': report.tx_errors, 'bus_error': report.bus_error,
                'bad_frames': counts_line(report.bad_frames),
                'last_bad_frame': report.last_bad_frame,
                'jog_received': counts.received, 'jog_refused': counts.refused,
                'jog_refused_by': counts_line(sorted(counts.refused_by.items())),
                'jog_clipped': counts.clipped, 'jog_superseded': counts.superseded,
                'jog_ignored': counts.ignored, 'last_ignored': counts.last_ignored,
                'last_refusal': counts.last_refusal, 'scheduling': self.scheduling(),
                'link': report.link, 'link_losses': report.link_losses,
                'link_outage': report.link_outage}))
        for j in report.joints:
            level = 'ERROR' if j.reference_lost else LEVELS[j.state]
            msg.status.append(make_status(
                f'driver: {j.name}', level,
                'reference lost: re-reference' if j.reference_lost else j.state, {
                    'state': j.state, 'flags': f'0x{j.flags:02X}',
                    'flag_names': ' '.join(j.flag_names), 'referenced': j.referenced,
                    'reference_required': j.reference_required,
                    'reference_lost': j.reference_lost,
                    'position': j.q, 'lag': j.lag, 'silent_cycles': j.silent_cycles}))
        self.pub_diag.publish(msg)


def hold_kind(hold: str) -> str:
    """Return why the arm holds without the counts that change every cycle."""
    return re.sub(r'\d+ cycles', 'N cycles', hold)


def counts_line(pairs: Iterable[tuple[str, int]]) -> str:
    """Return ``(name, count)`` pairs as one line, 'name count, ...' ('' for none)."""
    return ', '.join(f'{name} {count}' for name, count in pairs)
