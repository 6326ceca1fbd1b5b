"""
The state of the arm driver: each joint's record and state machine, the arm's, and the reports.

Per joint and for the arm the state is a ``ModuleState``: disconnected (no reply yet), connected
(replying, motor not enabled), error (a flag other than "motor not enabled"), enabled, referenced
(enabled and referenced), fault (silent). The arm's state is its worst joint's (``ARM_ORDER``),
or ``power_lost`` when every module reports its supply flag at once (brown-out on the Mover6's
modules, "e-stop or supply too low" on CAN V2 ones): the e-stop was pressed or the power went.
A joint whose scaling requires referencing holds the arm until its module reports the
referenced bit; a referenced bit that drops (a brown-out restarts the module) latches
``reference_lost``, which only a confirmed referencing clears (a reset does not).
``JointRecord`` is what the driver (``hardware.driver.ArmDriver``) keeps of one joint between
cycles; ``hold_reason`` says why the arm may not move; ``joint_report`` and ``arm_state`` make
the cycle's ``ArmReport``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Optional, Sequence

from mover6_control.hardware import protocol as p
from mover6_control.hardware.gripper import GripperReport
from mover6_control.hardware.scaling import JointScale


class ModuleState(StrEnum):
    """The state of a joint's motor module, and of the arm (its worst joint's)."""

    DISCONNECTED = 'disconnected'
    CONNECTED = 'connected'
    ERROR = 'error'
    ENABLED = 'enabled'
    REFERENCED = 'referenced'
    FAULT = 'fault'
    POWER_LOST = 'power_lost'


S = ModuleState
# Worst first: the arm takes the first of these that any joint is in.
ARM_ORDER = (S.FAULT, S.DISCONNECTED, S.ERROR, S.CONNECTED, S.ENABLED, S.REFERENCED)
# The states in which a module follows its set-points.
FOLLOWING = (S.ENABLED, S.REFERENCED)
# The flag by which a module says its supply went, per firmware (protocol.ERROR_FLAGS' names).
POWER_FLAGS = ('brown_out', 'estop_or_low_supply')
POWER_LOST_REASON = ('power lost (e-stop?): every module reports its supply flag (the e-stop was '
                     'pressed, or the supply went). Recovery: make the arm safe, release the '
                     'e-stop, then call ~/recover (reset, enable, re-reference)')


@dataclass(frozen=True)
class JointReport:
    """One joint at one cycle: ``q`` [rad], ``qd`` [rad/s], ``lag`` = set-point - q [rad]."""

    name: str
    state: str
    q: float
    qd: float
    setpoint: float
    lag: float
    flags: int
    flag_names: tuple[str, ...]
    referenced: bool
    silent_cycles: int
    replies: int
    reference_required: bool = False
    reference_lost: bool = False


@dataclass(frozen=True)
class ArmReport:
    """The arm at one cycle; ``hold`` is why it does not move ('' when it may)."""

    time: float
    state: str
    hold: str
    joints: tuple[JointReport, ...]
    period: float
    frames_dropped: int
    frames_bad: int
    tx_errors: int
    bus_error: str
    bad_frames: tuple[tuple[str, int], ...] = ()
    last_bad_frame: str = ''
    link: str = 'up'             # the link to the adapter: 'up' or 'lost'
    gripper: Optional[GripperReport] = None
    inputs: tuple[bool, ...] = ()   # the arm's digital inputs (joint 1's module), () unknown
    link_losses: int = 0         # links lost so far
    link_outage: float = 0.0     # [s] the last lost link's time to its reopening


class JointRecord:
    """The driver's mutable record of one joint (control thread only, under the lock)."""

    def __init__(self, scale: JointScale) -> None:
        self.scale = scale
        self.reply: Optional[p.Reply] = None
        self.reply_time: Optional[float] = None
        self.replies = 0
        self.ticks: Optional[int] = None          # measured, offset removed
        self.qd = 0.0
        self.setpoint: Optional[float] = None     # [ticks, float]
        self.velocity = 0.0        # commanded, [rad/s]
        self.silent = 0
        self.fault = False
        self.track = True          # set-point follows the measured position
        self.counter = 0           # the last set-point's counter byte (1..255: 0 is never sent)
        self.sent = {}             # counter -> (frame sequence, set-point [ticks]) sent lately
        self.echo_seq = -1         # sequence of the set-point the latest reply echoes (-1: none)
        self.echo_value = None     # that set-point [ticks]
        self.unknown_cycles = 0    # cycles without a position yet
        self.relearn = False       # a command may have moved or re-zeroed it: take the next reply
        self.outputs = 0
        self.reference_lost = False  # its referenced bit dropped: latched until re-referenced

    def forget(self) -> None:
        """Forget what was measured (the link to the modules went): unknown until they answer."""
        self.reply = self.reply_time = self.ticks = self.setpoint = self.echo_value = None
        self.replies = self.silent = self.unknown_cycles = 0
        self.qd = self.velocity = 0.0
        self.fault = self.relearn = False
        self.track = True
        self.sent = {}
        self.echo_seq = -1

    def next_counter(self) -> int:
        """Return the counter byte of the next set-point: 1..255, wrapping past 0."""
        self.counter = self.counter % 255 + 1
        return self.counter

    def primed(self, since: int) -> bool:
        """
        Tell whether the module answered a set-point sent after frame ``since`` at its position.

        Then the set-point the module holds is where the joint is (a module that keeps its last
        set-point while disabled goes nowhere when enabled).
        """
        return self.echo_seq > since and self.echo_value is not None and \
            self.ticks is not None and abs(self.echo_value - self.ticks) <= 1

    def state(self) -> ModuleState:
        """Return the joint's state from its latest reply (and a latched fault)."""
        if self.fault:
            return S.FAULT
        if self.reply is None:
            return S.DISCONNECTED
        flags = self.reply.error_flags
        if flags & ~0x04:
            return S.ERROR
        if flags & 0x04:
            return S.CONNECTED
        return S.REFERENCED if self.reply.referenced else S.ENABLED


def power_lost(flag_names: Sequence[Sequence[str]]) -> bool:
    """Tell whether every module's flags (their names, one tuple per joint) say power lost."""
    return bool(flag_names) and all(any(f in POWER_FLAGS for f in names)
                                    for names in flag_names)


def hold_reason(joints: Sequence[JointRecord], busy: set, firmware: str,
                enabling: bool = False) -> str:
    """
    Return why the arm must hold ('' when it may move).

    ``busy``: joints referencing or setting zero; ``enabling``: an enable is under way.
    """
    if all(j.reply is not None for j in joints) and power_lost(
            [p.flag_names(j.reply.error_flags, firmware) for j in joints]):
        return POWER_LOST_REASON
    if busy:
        return f'joints {sorted(busy)}: referencing or setting zero'
    if enabling:
        return 'enabling: every module first answers a set-point at its measured position'
    for j in joints:
        state = j.state()
        if state == S.FAULT:
            return f'{j.scale.name}: module silent for {j.silent} cycles'
        if j.silent:
            # Not yet a fault, but the driver does not know where the joint is: it does not
            # guess, the arm holds until the reply comes.
            return f'{j.scale.name}: {j.silent} reply(ies) missed, holds until it answers'
        if state == S.DISCONNECTED:
            return f'{j.scale.name}: no reply from its module yet'
        if state == S.ERROR:
            names = ', '.join(p.flag_names(j.reply.error_flags & ~0x04, firmware))
            return f'{j.scale.name}: error flags {names}'
        if state == S.CONNECTED:
            return f'{j.scale.name}: motor not enabled'
    for j in joints:
        if j.reference_lost:
            return (f'{j.scale.name}: reference lost (its referenced bit dropped): '
                    're-reference it (~/recover or ~/reference)')
        if j.scale.reference_required and not j.reply.referenced:
            return (f'{j.scale.name}: not referenced (referencing required): activate the '
                    'driver, or call ~/reference or ~/recover')
    return ''


def joint_report(j: JointRecord, firmware: str) -> JointReport:
    """Return the report of joint ``j`` now (NaN positions before its first reply)."""
    q = j.scale.to_rad(j.ticks) if j.ticks is not None else float('nan')
    sp = j.scale.to_rad(j.setpoint) if j.setpoint is not None else q
    flags = j.reply.error_flags if j.reply is not None else 0
    return JointReport(
        name=j.scale.name, state=j.state(), q=q, qd=j.qd, setpoint=sp, lag=sp - q,
        flags=flags, flag_names=p.flag_names(flags, firmware),
        referenced=bool(j.reply and j.reply.referenced), silent_cycles=j.silent,
        replies=j.replies, reference_required=j.scale.reference_required,
        reference_lost=j.reference_lost)


def arm_state(joints: Sequence[JointReport]) -> ModuleState:
    """Return the arm's state: power lost, or the worst of its joints' (``ARM_ORDER``)."""
    if all(r.replies for r in joints) and power_lost([r.flag_names for r in joints]):
        return S.POWER_LOST
    return next(s for s in ARM_ORDER if any(r.state == s for r in joints))
