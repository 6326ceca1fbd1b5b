"""
The arm driver's intake of the bus: each module's replies, everything else refused by reason.

``ReplyIntake.read`` takes every frame that arrived. What is not a reply of one of the joints'
modules is refused and counted by its reason (``ArmReport.bad_frames``), never decoded as a
position: a remote or error frame, an extended ID, an unknown ID, a command frame of another
master on the bus, a reply of the wrong length. So is a reply whose timestamp (``data[5]``) did
not move since the module's last one ('stale_timestamp': the vendor's ``Joint.cpp`` ignores such
a reply too), and a well-formed reply whose position the joint cannot have reached
('position_jump', ``setpoints.plausible``). Timestamp 0 is never a set-point's counter (the
driver sends 1..255): a reply carrying it answers a command, and is taken without that check.

A reply whose timestamp echoes the counter of a set-point the driver sent (the user guide: the
module copies the command's timestamp into its answer) proves that the module had that set-point
when it answered: the joint's ``echo_seq`` / ``echo_value`` keep the newest such set-point, and
confirmations (enable, reset, set zero, referencing) count only replies that echo a set-point
sent after their command. A module that has not answered a frame that went to it at least
``REPLY_GRACE`` before the read misses a reply (a frame still waiting in the outbox, behind a
burst of commands, is owed nothing yet); after ``silent_cycles`` missed in a row the joint is a
latched fault until a reset. Every frame read also goes to the frame log, if there is one
(refused ones included, all eight bytes: ``data[5]`` and ``data[6]`` as the module sent them).
With ``listen_only`` the set-points and commands of the master that drives the bus are expected:
they are logged, not counted as refused.
"""

from __future__ import annotations

from typing import Optional, Sequence

import can
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver_state import JointRecord
from mover6_control.hardware.outbox import Outbox
from mover6_control.hardware.setpoints import plausible

REPLY_GRACE = 0.01
"""[s] a frame sent this long before a read is owed a reply by then."""
COMMAND_STAMP = 0
"""A reply's timestamp that no set-point carries: the answer to a command (reset, disable...)."""


def frame_problem(msg: can.Message, n_joints: int) -> str:
    """Return why ``msg`` is no reply of one of ``n_joints`` modules ('' when it is one)."""
    if msg.is_error_frame or msg.is_remote_frame:
        return 'remote_or_error_frame'
    if msg.is_extended_id:
        return 'extended_id'
    try:
        joint, is_reply = p.joint_of_id(msg.arbitration_id)
    except p.ProtocolError:
        return 'unknown_id'
    if not is_reply:
        return 'command_of_another_master'
    if joint > n_joints:
        return 'unknown_id'
    return ''


class ReplyIntake:
    """Read the replies into ``joints`` (``JointRecord``), refusing what is no fresh reply."""

    def __init__(self, joints: Sequence[JointRecord], outbox: Outbox, silent_cycles: int,
                 frame_log: Optional[can.Listener] = None, listen_only: bool = False) -> None:
        """
        Take the joints' records; ``outbox`` tells when a frame last went to each module.

        A module that misses ``silent_cycles`` replies in a row faults; every frame read goes
        to ``frame_log``; ``listen_only``: another master's frames are expected.
        """
        self.joints = joints
        self.outbox = outbox
        self.frame_log = frame_log
        self.listen_only = bool(listen_only)
        self.silent_cycles = int(silent_cycles)
        self.bad = 0                  # frames refused
        self.bad_reasons = {}         # reason -> frames refused for it
        self.last_bad = ''
        self.bus_error = ''

    def read(self, bus: can.BusABC, now: float, max_lag: float, cycle: float) -> set:
        """Take every frame on ``bus`` at ``now`` [s]; return the joints that answered."""
        fresh = set()
        while True:
            try:
                msg = bus.recv(timeout=0.0)
            except can.CanError as err:
                self.bus_error = f'receive failed: {err}'
                break
            if msg is None:
                break
            if self.frame_log is not None:
                self.frame_log(msg)
            joint = self._take(msg, now, max_lag, cycle)
            if joint:
                fresh.add(joint)
        for n, j in enumerate(self.joints, start=1):
            sent = self.outbox.sent_at.get(p.command_id(n))
            if n in fresh:
                j.silent = 0
            elif j.reply is not None and sent is not None and sent > j.reply_time and \
                    sent <= now - REPLY_GRACE:
                j.silent += 1
                j.qd = 0.0
                if j.silent >= self.silent_cycles:
                    j.fault = True
        return fresh

    def _take(self, msg: can.Message, now: float, max_lag: float, cycle: float) -> int:
        """Take one frame into its joint's record; return the joint, or 0 when refused."""
        reason = frame_problem(msg, len(self.joints))
        if reason == 'command_of_another_master' and self.listen_only:
            return 0                         # the master that drives the bus: expected
        if not reason:
            joint = p.joint_of_id(msg.arbitration_id)[0]
            j = self.joints[joint - 1]
            try:
                reply = p.decode_reply(bytes(msg.data[:msg.dlc]))
            except p.ProtocolError:
                reason = 'wrong_length'
        if not reason and reply.timestamp != COMMAND_STAMP and j.reply is not None and \
                reply.timestamp == j.reply.timestamp:
            reason = 'stale_timestamp'
        if not reason:
            ticks = j.scale.from_wire(reply.position)
            if not plausible(j, ticks, now, max_lag, cycle):
                reason = 'position_jump'
        if reason:
            self._refuse(msg, reason)
            return 0
        if j.ticks is not None and j.reply_time is not None and now > j.reply_time:
            j.qd = j.scale.to_rad(ticks - j.ticks) / (now - j.reply_time)
        if j.reply is not None and j.reply.referenced and not reply.referenced and \
                j.scale.reference_required:
            j.reference_lost = True          # latched: only a confirmed referencing clears it
        j.reply, j.ticks, j.reply_time = reply, ticks, now
        j.replies += 1
        j.relearn = False
        sent = j.sent.get(reply.timestamp)
        if sent is not None and sent[0] > j.echo_seq:
            j.echo_seq, j.echo_value = sent
        return joint

    def _refuse(self, msg: can.Message, reason: str) -> None:
        self.bad += 1
        self.bad_reasons[reason] = self.bad_reasons.get(reason, 0) + 1
        data = bytes(msg.data[:msg.dlc]).hex(' ')
        self.last_bad = f'{reason}: id 0x{msg.arbitration_id:X} dlc {msg.dlc} [{data}]'
