"""
Jogging in the controller: servo commands in, one servo step per tick out (``control.servo``).

The commands are a flange twist (``on_twist``) or joint velocities (``on_joint_jog``).

Idle, a fresh command starts jogging; jogging, the next replaces it; it ends, at rest, once the
command goes stale. While a collision guard is set, the jog's next poses are checked by it too.

``Jogging`` is made with what it reads and changes: the arm (the servo's kinematics), the robot
(the measured position, the reference a demand would start from) and the ``CoreState`` it
shares with the other parts of ``controller_core.ControllerCore`` (the state machine, the
result, the settings and the collision guard). What only jogging keeps between commands and
ticks is its own ``JogSession`` (``session``), which the status reads. A test builds it alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Optional, Sequence

from mover6_control.control import state_machine as sm
from mover6_control.control.core_state import CoreState
from mover6_control.control.robot import Robot
from mover6_control.control.servo import (command_age, initial_state, joint_jog_command,
                                          servo_step, TwistCommand)
from mover6_control.control.status import Cause, MotionResult, StatusKey as K
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel


@dataclass(eq=False)
class JogSession:
    """
    What jogging keeps between commands and ticks.

    ``command``: the latest servo command (``control.servo``; None: none); ``servo_state``: the
    servo's state between ticks; ``kind``: 'free', 'slowed', 'halted' or 'stale' (a change is a
    status change); ``values``: the jogging figures for the status; ``refused``: why the latest
    jog command was refused ('' once one is taken); ``vetoed``: (servo config, collision guard,
    the two combined), made again only when either changes.
    """

    command: Optional[object] = None
    servo_state: Optional[object] = None
    kind: str = ''
    values: dict = field(default_factory=dict)
    refused: str = ''
    vetoed: tuple = (None, None, None)


class Jogging:
    """The jogging of one arm's controller (module docstring)."""

    def __init__(self, arm: ArmModel, robot: Robot, core_state: CoreState):
        """Jog ``arm`` (its model ``robot``), stepping ``core_state``'s state machine."""
        self.arm = arm
        self.robot = robot
        self.core_state = core_state
        self.session = JogSession()

    def on_twist(self, now: float, stamp: float, linear: Sequence[float],
                 angular: Sequence[float], frame: str = 'base_link') -> None:
        """
        Take a flange twist [m/s, rad/s] in ``frame`` stamped ``stamp`` [s], at ``now`` [s].

        Idle, a fresh command starts jogging; jogging, it replaces the previous command. Raises
        ``InvalidInputError`` with the reason (kept in the status as ``jog_refused``) for a bad
        command, a stamp from the future (``servo.FUTURE_STAMP_TOLERANCE`` after ``now``), or
        while a motion executes, settles or stops (stop it first), or in fault. The command
        goes stale ``servo_command_timeout`` after the earlier of its stamp and ``now``.
        """
        self._take_jog(now, lambda: TwistCommand(stamp, linear, angular, frame, now))

    def on_joint_jog(self, now: float, stamp: float, names: Sequence[str],
                     velocities: Sequence[float]) -> None:
        """Take joint velocities [rad/s] by joint name, stamped ``stamp`` [s]; as ``on_twist``."""
        self._take_jog(now, lambda: joint_jog_command(self.arm, stamp, names, velocities, now))

    def _take_jog(self, now, make):
        try:
            command = make()
            state = self.core_state.state
            if state != sm.JOGGING:
                if state != sm.IDLE:
                    hint = '; stop the motion first' if state in sm.MOVING_STATES else ''
                    raise InvalidInputError(f'jogging refused while {state}: '
                                            f'{self.core_state.message}{hint}')
                timeout = self.core_state.config.servo.command_timeout
                if command_age(command, now) > timeout:
                    raise InvalidInputError(f'jog command older than the timeout {timeout:g} s '
                                            'by its stamp')
        except InvalidInputError as err:
            self.note_jog_refused(str(err))
            raise
        session, shared = self.session, self.core_state
        session.command = command
        if session.refused:
            session.refused, shared.changed = '', True
        if shared.state == sm.IDLE:
            session.servo_state = initial_state(self.arm)
            session.kind = ''
            shared.result = {}
            self.core_state.step(sm.JOG, 'OK', 'jogging')

    def note_jog_refused(self, reason: str) -> None:
        """Keep why a jog command was refused (status: ``jog_refused``) until one is taken."""
        session = self.session
        if session.refused != reason:     # a stream of the same refusal: one status change
            session.refused, self.core_state.changed = reason, True

    def tick(self, now: float):
        """Return this tick's jogging command; back to idle once stale and at rest."""
        q, session, shared = self.robot.q, self.session, self.core_state
        servo, guard = shared.config.servo, shared.collision_guard
        if guard is not None and servo.veto is None:     # the jog's next poses are checked too
            if session.vetoed[0] is not servo or session.vetoed[1] is not guard:
                session.vetoed = (servo, guard, replace(servo, veto=guard.veto))
            servo = session.vetoed[2]
        out = servo_step(self.arm, servo, session.servo_state, session.command, q, now,
                         shared.derived.dt, shared.derived.velocity_limits)
        session.servo_state = out.state
        self.robot.reference = (q, out.qd)      # a demand now starts from the jog's velocity
        kind = ('stale' if out.stale else 'halted' if out.halted
                else 'slowed' if out.scale < 1.0 else 'free')
        session.values = {K.JOG_REASON: out.reason, K.JOG_CONDITION: f'{out.condition:.2f}',
                          K.JOG_SCALE: f'{out.scale:.3f}'}
        shared.message = f'jogging: {out.reason}' if out.reason else 'jogging'
        shared.level = 'OK' if kind in ('free', 'stale') else 'WARN'
        if kind != session.kind:
            session.kind, shared.changed = kind, True
        if out.stale and out.at_rest:
            shared.result = {K.RESULT: MotionResult.JOG_STOPPED, K.CAUSE: Cause.JOG_ENDED,
                             K.REASON: out.reason}
            self.core_state.step(sm.JOG_DONE, 'OK', f'jog ended, at rest: {out.reason}; idle')
            return None
        return out.qd
