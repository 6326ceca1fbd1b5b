"""
The arm driver's intake of the bus: each module's replies, everything else dropped by reason.

Each cycle ``_read`` takes every frame that arrived. What is not a reply of one of the joints'
modules is dropped and counted by its reason (``ArmReport.bad_frames``), never decoded as a
position: a remote or error frame, an extended ID, an unknown ID, a command frame of another
master on the bus, a reply of the wrong length. A well-formed reply whose position the joint
cannot have reached is dropped too ('position_jump', ``setpoints.plausible``). A joint whose
module sent nothing this cycle counts a silent cycle; after ``silent_cycles`` it is a latched
fault until a reset.

``DriverReplies`` is a part of ``hardware.driver.ArmDriver`` (its state is the driver's, set in
``ArmDriver.__init__``); it is not used on its own.
"""

from __future__ import annotations

import can
from mover6_control.hardware import protocol as p
from mover6_control.hardware.setpoints import plausible


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


class DriverReplies:
    """The bus intake of ``ArmDriver`` (module docstring)."""

    def _read(self, now: float) -> None:
        fresh = set()
        while True:
            try:
                msg = self.bus.recv(timeout=0.0)
            except can.CanError as err:
                self._bus_error = f'receive failed: {err}'
                break
            if msg is None:
                break
            reason = frame_problem(msg, len(self._joints))
            if not reason:
                joint = p.joint_of_id(msg.arbitration_id)[0]
                try:
                    reply = p.decode_reply(bytes(msg.data[:msg.dlc]))
                except p.ProtocolError:
                    reason = 'wrong_length'
            if not reason:
                j = self._joints[joint - 1]
                ticks = j.scale.from_wire(reply.position)
                if not plausible(j, ticks, now, self.max_lag, self.cycle):
                    reason = 'position_jump'
            if reason:
                self._refuse_frame(msg, reason)
                continue
            if j.ticks is not None and j.reply_time is not None and now > j.reply_time:
                j.qd = j.scale.to_rad(ticks - j.ticks) / (now - j.reply_time)
            j.reply, j.ticks, j.reply_time = reply, ticks, now
            j.replies += 1
            fresh.add(joint)
        for n, j in enumerate(self._joints, start=1):
            if n in fresh:
                j.silent = 0
            elif j.reply is not None:
                j.silent += 1
                j.qd = 0.0
                if j.silent >= self.silent_cycles:
                    j.fault = True

    def _refuse_frame(self, msg: can.Message, reason: str) -> None:
        self._bad += 1
        self._bad_reasons[reason] = self._bad_reasons.get(reason, 0) + 1
        data = bytes(msg.data[:msg.dlc]).hex(' ')
        self._last_bad = f'{reason}: id 0x{msg.arbitration_id:X} dlc {msg.dlc} [{data}]'
