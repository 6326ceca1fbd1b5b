"""
The arm driver's requests to the modules: reset, enable, disable, reference, set zero.

``Requests.submit`` (any thread, under the driver's lock) checks a request and queues it, or
refuses it at once with the reason. The control thread then queues its frames (``start``; enable,
referencing and set zero go twice, ``REPEAT_DELAY`` apart, as the vendor's driver does) and
answers it (``check``) once every addressed module confirms it in a reply that echoes a set-point
sent after the request's last frame (``JointRecord.echo_seq``): a reply that was on its way when
the command went out confirms nothing. Otherwise it times out, with what is missing.

Enable is all six modules or none, in three steps:

1. refused at once unless every module has answered, none is faulted (silent for
   ``silent_cycles``) and none reports an error flag but "motor not enabled" (reset first);
2. every module answers a set-point at its measured position (``JointRecord.primed``): a module
   that keeps its last set-point while disabled then goes nowhere when it is enabled;
3. enable goes to all six; once all six report no flag in a reply after it, it is confirmed. A
   module that reports an error, goes silent or does not enable in time disables all six, and the
   request is refused with the reason.

Referencing and set zero are refused while the arm moves; referencing needs its joint enabled,
set zero its joints disabled. A module that stops while it references (an error flag, its motor
no longer enabled, in a reply after the command: its communication watchdog, a lag) refuses the
referencing at once with its flags: it drives no more to its switch, so waiting for the
referenced bit would only run out the timeout, and a referenced bit in a reply that reports the
module stopped confirms nothing. Set zero sends the value that makes the joint read angle 0 (its
offset: 500 for J5, 509 for J6, 0 for J1..J4) in the frame's last two bytes.
"""

from __future__ import annotations

import threading
from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver_state import FOLLOWING, JointRecord, ModuleState
from mover6_control.hardware.outbox import Outbox

REPEAT_DELAY = 0.02
"""Delay between the two frames of enable, start referencing and set zero [s]."""
REPEATED = ('enable', 'reference', 'set_zero')


class Request:
    """A command to the modules; ``wait`` blocks until it is confirmed, refused or timed out."""

    def __init__(self, kind: str, joints: tuple[int, ...], timeout: float) -> None:
        self.kind = kind
        self.joints = joints
        self.timeout = timeout
        self.sent: Optional[float] = None     # when its first frame was queued [s]
        self.first_seq = -1                  # the outbox's sequence before its first frame
        self.last_seq = -1                   # the sequence of its last frame (-1: not yet sent)
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


class Requests:
    """The requests of the arm driver to the modules of ``joints`` (module docstring)."""

    def __init__(self, joints: Sequence[JointRecord], outbox: Outbox, firmware: str) -> None:
        """Address the modules of ``joints`` through ``outbox``; ``firmware`` names the flags."""
        self.joints = joints
        self.outbox = outbox
        self.firmware = firmware
        self._queue: list[Request] = []

    # --- any thread (under the driver's lock) ---

    def submit(self, kind: str, joints: Optional[Sequence[int]], timeout: float,
               moving: bool) -> Request:
        """Check and queue ``kind`` for ``joints`` (default all); ``moving``: the arm moves."""
        if kind not in p.COMMAND_FRAMES:
            raise InvalidInputError(f'request must be one of {sorted(p.COMMAND_FRAMES)}, '
                                    f'got {kind!r}')
        everyone = tuple(range(1, len(self.joints) + 1))
        targets = everyone if joints is None else tuple(joints)
        for n in targets:
            if n not in everyone:
                raise InvalidInputError(f'joint must be in 1..{len(self.joints)}, got {n!r}')
        req = Request(kind, targets, float(timeout))
        refusal = self._refusal(req, moving)
        if refusal:
            req.finish(False, f'{kind} refused: {refusal}')
        elif kind == 'enable' and all(j.state() in FOLLOWING for j in self.joints):
            req.finish(True, 'enable: all six already enabled')
        else:
            self._queue.append(req)
        return req

    def _refusal(self, req: Request, moving: bool) -> str:
        """Return why ``req`` cannot be done safely now ('' when it can be queued)."""
        chosen = [self.joints[n - 1] for n in req.joints]
        if req.kind == 'enable':
            if len(req.joints) != len(self.joints):
                return 'enable is all six modules or none'
            if any(r.kind == 'enable' for r in self._queue):
                return 'an enable is under way'
            for j in self.joints:
                problem = self._not_ready(j)
                if problem:
                    return f'{j.scale.name}: {problem} (all six modules or none)'
        if req.kind in ('reference', 'set_zero') and moving:
            return 'the arm is moving'
        if req.kind == 'set_zero':
            if any(j.state() in FOLLOWING for j in chosen):
                return ('disable the motors first (an enabled module would follow a set-point '
                        'sent before the zero)')
            if any(j.ticks is None for j in chosen):
                return 'a module has not answered yet'
        if req.kind == 'reference' and any(j.state() not in FOLLOWING for j in chosen):
            return 'the joint must be enabled first'
        return ''

    def _not_ready(self, j: JointRecord) -> str:
        """
        Return why ``j``'s module may not be enabled now ('' when it may).

        A module that missed a reply or two is not refused here (a loaded machine delays one now
        and then): it must still answer a set-point at its position before enable goes out, and
        ``silent_cycles`` missed in a row (a fault) stop the enable on all six.
        """
        state = j.state()
        if state == ModuleState.DISCONNECTED:
            return 'no reply from its module'
        if state == ModuleState.FAULT:
            return f'its module is silent ({j.silent} replies missed): reset first'
        if state == ModuleState.ERROR:
            names = ', '.join(p.flag_names(j.reply.error_flags & ~p.NOT_ENABLED, self.firmware))
            return f'error flags {names}: reset first'
        return ''

    # --- the control thread ---

    def busy_joints(self) -> set:
        """Return the joints a queued referencing or set zero is working on."""
        return {n for r in self._queue if r.kind in ('reference', 'set_zero') for n in r.joints}

    def enabling(self) -> bool:
        """Tell whether an enable is under way (the arm holds, set-points track)."""
        return any(r.kind == 'enable' for r in self._queue)

    def start(self, now: float) -> None:
        """Queue the frames of the requests that came since the last cycle (enable waits)."""
        for req in self._queue:
            if req.sent is not None:
                continue
            req.sent, req.first_seq = now, self.outbox.seq
            if req.kind == 'enable':
                continue                     # its frames go once the modules are primed
            for n in req.joints:
                j = self.joints[n - 1]
                if req.kind == 'reset' and j.fault:
                    # Silent until now: its last position is stale, read it again (disable
                    # until it answers) rather than send it behind the reset.
                    j.forget()
                j.track = True
                j.relearn = req.kind in ('reset', 'set_zero', 'reference')
                if req.kind == 'reset':
                    j.fault, j.silent = False, 0
            self._send(req, now)

    def after_setpoints(self, now: float) -> None:
        """Send enable once every module answered a set-point at its position."""
        for req in self._queue:
            if req.kind == 'enable' and req.last_seq < 0 and \
                    all(j.primed(req.first_seq) for j in self.joints):
                self._send(req, now)

    def _send(self, req: Request, now: float) -> None:
        """Queue the frames of ``req`` (twice, ``REPEAT_DELAY`` apart, where it needs it)."""
        frames = [(n, self._frame(req.kind, n)) for n in req.joints]
        for n, data in frames:
            req.last_seq = self.outbox.put(p.command_id(n), data, now)
        if req.kind in REPEATED:
            for n, data in frames:
                req.last_seq = self.outbox.put(p.command_id(n), data, now, now + REPEAT_DELAY)

    def _frame(self, kind: str, n: int) -> bytes:
        """Return the payload of ``kind`` for joint ``n``."""
        if kind == 'set_zero':
            return p.encode_set_zero(self.joints[n - 1].scale.offset)
        return p.COMMAND_FRAMES[kind]

    def check(self, now: float) -> list[Request]:
        """Answer the requests that are confirmed, failed or timed out; return them."""
        done = []
        for req in list(self._queue):
            if req.sent is None:
                continue
            missing, failed = self._confirmation(req)
            if not missing:
                if req.kind == 'reference':
                    for n in req.joints:
                        self.joints[n - 1].reference_lost = False
                req.finish(True, f'{req.kind}: confirmed by joints {list(req.joints)}')
            elif failed or now - req.sent >= req.timeout:
                why = missing if failed else f'not confirmed within {req.timeout} s ({missing})'
                if req.kind == 'enable':
                    self._disable_all(now)
                    why += '; all six disabled'
                req.finish(False, f'{req.kind}: {why}')
            if req.ok is not None:
                self._queue.remove(req)
                done.append(req)
        return done

    def _disable_all(self, now: float) -> None:
        for n in range(1, len(self.joints) + 1):
            self.outbox.put(p.command_id(n), p.DISABLE, now)
            self.joints[n - 1].track = True

    def _confirmation(self, req: Request) -> tuple[str, bool]:
        """Return (what is missing, whether it failed for good); ('', False) once confirmed."""
        if req.kind == 'enable':
            for j in self.joints:
                problem = self._not_ready(j)
                if problem:
                    return f'{j.scale.name}: {problem}', True
            if req.last_seq < 0:
                waiting = [j.scale.name for j in self.joints if not j.primed(req.first_seq)]
                return (f'{", ".join(waiting)}: no reply to a set-point at the measured position '
                        '(moving while disabled?)'), False
        for n in req.joints:
            j = self.joints[n - 1]
            if j.reply is None or j.echo_seq <= req.last_seq:
                return f'{j.scale.name}: no reply to a set-point sent since the command', False
            flags = j.reply.error_flags
            if req.kind == 'reference' and j.state() not in FOLLOWING:
                # The module stopped (its watchdog, a lag, an error): it drives no more to its
                # switch, and a referenced bit in the same reply is no referencing done.
                names = ', '.join(p.flag_names(flags & ~p.NOT_ENABLED, self.firmware))
                return (f'{j.scale.name}: module stopped while referencing ('
                        f'{names or "motor not enabled"}): reset and enable, then reference '
                        'again'), True
            missing = {
                'reset': flags & ~p.NOT_ENABLED and 'error flags still set: ' + ', '.join(
                    p.flag_names(flags & ~p.NOT_ENABLED, self.firmware)),
                'enable': flags and 'flags ' + ', '.join(p.flag_names(flags, self.firmware)),
                'disable': not flags & p.NOT_ENABLED and 'motor still enabled',
                'reference': not j.reply.referenced and 'not referenced yet',
                'set_zero': abs(j.ticks) > 1 and f'position {j.ticks} ticks, not zero',
            }[req.kind]
            if missing:
                return f'{j.scale.name}: {missing}', False
        return '', False

    def finish_all(self, reason: str) -> None:
        """Answer every queued request with ``reason`` (the driver shuts down)."""
        for req in self._queue:
            req.finish(False, f'{req.kind}: {reason}')
        self._queue = []
