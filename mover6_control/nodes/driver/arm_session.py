"""
The driver's arm between configure and cleanup: one ``ArmDriver``, its requests in order.

ROS-free; the lifecycle node (``node``) calls it from its transitions and services, each
call answering (success, message):

- ``configure``: the bus and the driver, then every module's position, read with
  commands that move nothing (the driver probes each module with ``disable``); it fails when a
  module has not answered within ``request_timeout``, and the bus is closed again;
- ``activate``: reset, enable (all six modules or none) and referencing of every joint that
  requires it and is not referenced, one at a time in the joint file's order;
- ``deactivate``: the command stops (the set-points stay where they are), the arm comes to rest
  (or ``SETTLE_TIME`` passes), every module is disabled;
- ``close`` (cleanup, shutdown, error): every module disabled, the bus closed;
- ``run(kind)``: one Trigger service (reset, enable, disable, reference, set_zero);
- ``recover``: reset + enable + (re)referencing in one call.

Power: once every module reported its supply flag at once (the arm state ``power_lost``: the
e-stop, or the supply went), the session latches it: enable and referencing are refused with
the reason until ``recover`` succeeds, and ``recover`` is refused with the reason while the flag
still stands after its reset (the e-stop is still pressed).
"""

from __future__ import annotations

import threading
import time
from typing import Callable, Optional

from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.driver_state import ArmReport, ModuleState, POWER_LOST_REASON

SETTLE_TIME = 1.0
"""[s] deactivate waits at most this long for the arm to come to rest before disabling."""
SETTLED_SPEED = 1e-3
"""[rad/s] below this on every joint the arm is at rest."""
Timeouts = Callable[[], tuple[float, float]]


class ArmSession:
    """
    The arm while the driver is configured (module docstring).

    ``open_driver(on_cycle)`` makes the ``ArmDriver`` (the bus opened, the frame log too);
    ``timeouts()`` gives the live (request_timeout, reference_timeout) [s]; ``on_cycle`` gets
    every cycle's report after the session has seen it; ``allow_set_zero()`` the live guard.
    """

    def __init__(self, open_driver: Callable[[Callable], ArmDriver], timeouts: Timeouts,
                 on_cycle: Callable[[ArmReport], None],
                 allow_set_zero: Callable[[], bool]) -> None:
        self.open_driver = open_driver
        self.timeouts = timeouts
        self.on_cycle = on_cycle
        self.allow_set_zero = allow_set_zero
        self.driver: Optional[ArmDriver] = None
        self.power_latched = False
        self._cycled = threading.Condition()
        self._report: Optional[ArmReport] = None

    # --- configure / cleanup ---

    def configure(self) -> tuple[bool, str]:
        """Open the bus and read every module's position; (False, reason) closes it again."""
        self.power_latched = False
        self.driver = self.open_driver(self._on_cycle)
        self.driver.start()
        if self.driver.listen_only:
            return True, 'configured listen_only: the driver sends nothing'
        timeout = self.timeouts()[0]
        if not self._wait(lambda r: all(j.replies for j in r.joints), timeout):
            report = self._report
            silent = [j.name for j in report.joints if not j.replies] if report else ['all']
            self.close()
            return False, (f'no position from {", ".join(silent)} within {timeout} s (is the '
                           'arm powered and the cable in?); the bus is closed again')
        q = ', '.join(f'{j.q:.4f}' for j in self._report.joints)
        return True, f'every module answered a command that moves nothing: q [rad] {q}'

    def close(self) -> None:
        """Disable every module and close the bus (nothing when not open)."""
        driver, self.driver = self.driver, None
        if driver is not None:
            driver.close()

    # --- activate / deactivate ---

    def activate(self) -> tuple[bool, str]:
        """Reset, enable, reference what needs it; (False, reason) leaves the arm disabled."""
        if self.driver is None:
            return False, 'activate refused: not configured'
        if self.driver.listen_only:
            return False, 'activate refused: listen_only, the driver sends nothing'
        if self.power_latched:
            return False, f'activate refused: {POWER_LOST_REASON}'
        steps = []
        for kind in ('reset', 'enable'):
            ok, message = self._request(kind)
            if not ok:
                return False, message
            steps.append(message)
        ok, message = self.reference()
        if not ok:
            self._request('disable')
            return False, message
        return True, '; '.join(steps + [message])

    def deactivate(self) -> tuple[bool, str]:
        """Stop the command, let the arm come to rest, disable every module."""
        if self.driver is None or self.driver.listen_only:
            return True, 'nothing to disable'
        self.driver.set_velocity([0.0] * len(self.driver.names))
        rest = self._wait(lambda r: all(abs(j.qd) < SETTLED_SPEED for j in r.joints), SETTLE_TIME,
                          fresh=2)
        ok, message = self._request('disable')
        return ok, ('at rest, ' if rest else f'not at rest after {SETTLE_TIME} s, ') + message

    # --- services ---

    def run(self, kind: str) -> tuple[bool, str]:
        """Run one Trigger service's request; return (success, message)."""
        if kind == 'set_zero' and not self.allow_set_zero():
            return False, 'set_zero refused: set the parameter allow_set_zero to true first'
        if self.driver is None:
            return False, f'{kind} refused: the driver is not configured'
        if kind in ('enable', 'reference') and self.power_latched:
            return False, f'{kind} refused: {POWER_LOST_REASON}'
        if kind == 'reference':
            return self.reference(everything=True)
        return self._request(kind)

    def recover(self) -> tuple[bool, str]:
        """Reset, enable and (re)reference in one call; refused while power is still lost."""
        if self.driver is None:
            return False, 'recover refused: the driver is not configured'
        ok, message = self._request('reset')
        if not ok:
            if self.power_latched or self._power_lost_now():
                return False, f'recover refused: power still lost after a reset ({message}): ' \
                              f'{POWER_LOST_REASON}'
            return False, f'recover: {message}'
        self.power_latched = False
        ok, enabled = self._request('enable')
        if not ok:
            return False, f'recover: {enabled}'
        ok, referenced = self.reference()
        if not ok:
            return False, f'recover: {referenced}'
        return True, f'recover: {message}; {enabled}; {referenced}'

    def reference(self, everything: bool = False) -> tuple[bool, str]:
        """
        Run the referencing of the joints that require it, one at a time in their order.

        Only those not referenced or whose reference was lost, unless ``everything``.
        """
        report = self._report
        scales = sorted(self.driver.joint_scales, key=lambda s: (s.reference_order, s.module))
        todo = []
        for s in scales:
            joint = report.joints[s.module - 1] if report else None
            if s.reference_required and (everything or joint is None or not joint.referenced
                                         or joint.reference_lost):
                todo.append(s)
        if not todo:
            return True, 'reference: every joint that requires it is referenced'
        timeout = self.timeouts()[1]
        for s in todo:
            ok, reason = self.driver.request('reference', [s.module], timeout).wait(
                timeout + 5.0)
            if not ok:
                return False, reason
        return True, f'reference: {", ".join(s.name for s in todo)} referenced in that order'

    # --- the reports ---

    def _on_cycle(self, report: ArmReport) -> None:
        if report.state == ModuleState.POWER_LOST:
            self.power_latched = True
        with self._cycled:
            self._report = report
            self._cycled.notify_all()
        self.on_cycle(report)

    def _power_lost_now(self) -> bool:
        report = self._report
        return report is not None and report.state == ModuleState.POWER_LOST

    def _wait(self, done: Callable[[ArmReport], bool], timeout: float, fresh: int = 0) -> bool:
        """Wait until a report (after ``fresh`` new ones) satisfies ``done``; False on timeout."""
        deadline = time.monotonic() + timeout
        seen = 0
        last = None
        with self._cycled:
            while True:
                report = self._report
                if report is not last:
                    seen += last is not None
                    last = report
                    if report is not None and seen >= fresh and done(report):
                        return True
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cycled.wait(left)

    def _request(self, kind: str) -> tuple[bool, str]:
        timeout = self.timeouts()[0]
        return self.driver.request(kind, timeout=timeout).wait(timeout + 5.0)
