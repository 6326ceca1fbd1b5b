"""
The Mover6 gripper as the driver knows it: what it was told, and where that puts it by now.

The gripper hangs on joint 4's digital outputs (``protocol.encode_gripper``) and reports
nothing back: no position, no force. ``GripperModel`` keeps the last command and estimates the
opening from it and the time since, moving at ``STROKE / STROKE_TIME``; that estimate is what
``/joint_states`` shows as the joint ``gripper`` (a prismatic joint in config/mover6.urdf, the
gap from 0 closed to ``STROKE`` open). Before the first command the gripper is taken as closed
(de-energised it may be anywhere: the first command settles it). Pure: time is an argument.

``STROKE`` and ``STROKE_TIME`` are this package's assumptions, not the vendor's (no source gives
them): measure them on the real gripper (time an open and a close) and set them here.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.hardware import protocol as p

NAME = 'gripper'
"""The gripper's joint in /joint_states and in config/mover6.urdf."""
STROKE = 0.03
"""[m] the gap of the open gripper (assumed; closed is 0)."""
STROKE_TIME = 1.0
"""[s] from closed to open or back (assumed)."""


@dataclass(frozen=True)
class GripperReport:
    """The gripper at one cycle: ``position`` [m] the estimated gap, ``velocity`` [m/s]."""

    command: str
    position: float
    velocity: float
    moving: bool


class GripperModel:
    """The last gripper command and the estimated gap (module docstring)."""

    def __init__(self, stroke: float = STROKE, stroke_time: float = STROKE_TIME) -> None:
        """Start closed and not driven; the gap runs ``stroke`` [m] in ``stroke_time`` [s]."""
        self.stroke = float(stroke)
        self.speed = self.stroke / float(stroke_time)
        self.command = 'off'
        self._from = 0.0          # the gap when the last command came [m]
        self._since = None        # when it came [s]

    def command_at(self, command: str, now: float) -> None:
        """Take ``command`` (off, open, closed; ProtocolError for another) at ``now`` [s]."""
        p.encode_gripper(command)
        if command == self.command:
            return
        self._from = self.position(now)
        self._since = now
        self.command = command

    def target(self) -> float:
        """Return the gap [m] the last command drives to (where it is, when off)."""
        return {'open': self.stroke, 'closed': 0.0}.get(self.command, self._from)

    def position(self, now: float) -> float:
        """Return the estimated gap at ``now`` [s] [m]."""
        if self._since is None or self.command == 'off':
            return self._from
        travel = self.speed * max(0.0, now - self._since)
        goal = self.target()
        if abs(goal - self._from) <= travel:
            return goal
        return self._from + travel * (1.0 if goal > self._from else -1.0)

    def arrival(self, now: float) -> float:
        """Return how long until the gap reaches the command's target, from ``now`` [s]."""
        return abs(self.target() - self.position(now)) / self.speed

    def report(self, now: float) -> GripperReport:
        """Return the gripper at ``now`` [s]."""
        left = self.arrival(now)
        goal = self.target()
        q = self.position(now)
        velocity = 0.0 if left <= 0.0 else self.speed * (1.0 if goal > q else -1.0)
        return GripperReport(self.command, q, velocity, left > 0.0)
