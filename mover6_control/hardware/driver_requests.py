"""
The arm driver's requests to the modules: reset, enable, disable, reference, set zero.

``request`` (any thread) checks and queues a ``Request``; the control thread sends its frames
in bus order at the next cycle (enable, reference and set zero go twice, ``REPEAT_DELAY``
apart, as the vendor's driver does) and answers it once every addressed module confirms it in
a reply received after it was sent, or refuses it at once, or times it out, with the reason.
Referencing and set zero are refused while the arm moves; referencing needs its joint enabled,
set zero its joints disabled.

``DriverRequests`` is a part of ``hardware.driver.ArmDriver`` (its state is the driver's, set in
``ArmDriver.__init__``: ``_joints``, ``_requests``, ``_scheduled``, ``_lock``, ``firmware``); it
is not used on its own.
"""

from __future__ import annotations

import threading
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver_state import FOLLOWING

REPEAT_DELAY = 0.02
"""Delay between the two frames of enable, start referencing and set zero [s]."""


class Request:
    """A command to the modules; ``wait`` blocks until it is confirmed, refused or timed out."""

    def __init__(self, kind: str, joints: tuple[int, ...], timeout: float) -> None:
        self.kind = kind
        self.joints = joints
        self.timeout = timeout
        self.sent: Optional[float] = None
        self.ok: Optional[bool] = None
        self.reason = ''
        self._done = threading.Event()

    def finish(self, ok: bool, reason: str) -> None:
        """Record the answer and wake the waiter (first answer wins)."""
        if self.ok is None:
            self.ok, self.reason = ok, reason
            self._done.set()

    def wait(self, timeout: Optional[float] = None) -> tuple[bool, str]:
        """Return (ok, reason) once answered; (False, reason) if ``timeout`` [s] passes first."""
        if not self._done.wait(timeout):
            return False, f'{self.kind}: no answer from the driver within {timeout} s'
        return self.ok, self.reason


class DriverRequests:
    """The requests of ``ArmDriver`` (module docstring)."""

    def request(self, kind: str, joints: Optional[Sequence[int]] = None,
                timeout: float = 2.0) -> Request:
        """
        Queue ``kind`` (reset, enable, disable, reference, set_zero) for ``joints`` (default all).

        Referencing and set zero are refused while the arm moves; referencing needs its joint
        enabled, set zero its joints disabled. The control thread sends the frames at its next
        cycle.
        """
        if kind not in p.COMMAND_FRAMES:
            raise InvalidInputError(f'request must be one of {sorted(p.COMMAND_FRAMES)}, '
                                    f'got {kind!r}')
        targets = tuple(range(1, len(self._joints) + 1)) if joints is None else tuple(joints)
        for n in targets:
            if n not in range(1, len(self._joints) + 1):
                raise InvalidInputError(f'joint must be in 1..{len(self._joints)}, got {n!r}')
        req = Request(kind, targets, float(timeout))
        with self._lock:
            if kind in ('reference', 'set_zero') and self._moving():
                req.finish(False, f'{kind} refused: the arm is moving')
            elif kind == 'set_zero' and any(
                    self._joints[n - 1].state() in FOLLOWING for n in targets):
                req.finish(False, 'set_zero refused: disable the motors first (an enabled '
                                  'module would follow a set-point sent before the zero)')
            elif kind == 'reference' and any(
                    self._joints[n - 1].state() not in FOLLOWING for n in targets):
                req.finish(False, 'reference refused: the joint must be enabled first')
            else:
                self._requests.append(req)
        return req

    def _busy_joints(self) -> set:
        """Return the joints a queued referencing or set zero is working on."""
        return {n for r in self._requests if r.kind in ('reference', 'set_zero')
                for n in r.joints}

    def _send_requests(self, now: float) -> None:
        for req in self._requests:
            if req.sent is not None:
                continue
            req.sent = now
            data = p.COMMAND_FRAMES[req.kind]
            for n in req.joints:
                self._send(p.command_id(n), data)
                if req.kind in ('enable', 'reference', 'set_zero'):
                    self._scheduled.append((now + REPEAT_DELAY, p.command_id(n), data))
                if req.kind in ('reset', 'reference', 'set_zero', 'enable', 'disable'):
                    j = self._joints[n - 1]
                    j.track = True
                    if req.kind == 'reset':
                        j.fault, j.silent = False, 0

    def send_due(self, now: float) -> None:
        """Send the repeated frames that are due at ``now`` [s] (the control thread's job)."""
        with self._lock:
            self._send_due(now)

    def _send_due(self, now: float) -> None:
        due = [s for s in self._scheduled if s[0] <= now]
        self._scheduled = [s for s in self._scheduled if s[0] > now]
        for _, can_id, data in due:
            self._send(can_id, data)

    def next_due(self) -> Optional[float]:
        """Return when the next repeated frame is due [s], or None."""
        with self._lock:
            return min((s[0] for s in self._scheduled), default=None)

    def _confirmed(self, req: Request) -> str:
        """Return '' once every addressed module confirms ``req``, else what is missing."""
        for n in req.joints:
            j = self._joints[n - 1]
            if j.reply is None or j.reply_time is None or j.reply_time <= req.sent:
                return f'{j.scale.name}: no reply since the command'
            flags = j.reply.error_flags
            missing = {
                'reset': flags & ~0x04 and 'error flags still set: ' + ', '.join(
                    p.flag_names(flags & ~0x04, self.firmware)),
                'enable': flags and 'flags ' + ', '.join(p.flag_names(flags, self.firmware)),
                'disable': not flags & 0x04 and 'motor still enabled',
                'reference': not j.reply.referenced and 'not referenced yet',
                'set_zero': abs(j.ticks) > 1 and f'position {j.ticks} ticks, not zero',
            }[req.kind]
            if missing:
                return f'{j.scale.name}: {missing}'
        return ''

    def _check_requests(self, now: float) -> None:
        for req in list(self._requests):
            missing = self._confirmed(req)
            if not missing:
                req.finish(True, f'{req.kind}: confirmed by joints {list(req.joints)}')
            elif now - req.sent >= req.timeout:
                req.finish(False, f'{req.kind}: not confirmed within {req.timeout} s ({missing})')
            if req.ok is not None:
                self._requests.remove(req)

    def _finish_all(self, reason: str) -> None:
        """Answer every queued request with ``reason`` (the driver shuts down)."""
        for req in self._requests:
            req.finish(False, f'{req.kind}: {reason}')
        self._requests = []
