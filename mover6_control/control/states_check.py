"""
The joint states' check that opens every tick: stale, incomplete or non-finite states fault.

``StatesCheck.check(now)`` reads the robot's measured states (``Robot.states_problem``: older
than ``state_timeout``, reported incomplete or non-finite, or distrusted) and steps the state
machine: a problem while not in fault drops the motion or jog (result 'fault') and enters the
fault at once; fresh valid states end the wait for the first ones, and recover from a fault when
they are newer than the fault. Before the first valid states it only keeps the status message
saying why they are not taken. A test builds it alone from a ``Robot`` and a ``CoreState``.
"""

from __future__ import annotations

from mover6_control.control import state_machine as sm
from mover6_control.control.core_state import CoreState
from mover6_control.control.robot import Robot
from mover6_control.control.status import Cause, MotionResult, StatusKey as K


class StatesCheck:
    """The joint states' check of one arm's controller (module docstring)."""

    def __init__(self, robot: Robot, core_state: CoreState):
        """Check ``robot``'s measured states, stepping ``core_state``'s state machine."""
        self.robot = robot
        self.core_state = core_state

    def check(self, now: float) -> None:
        """Fault on a problem with the states at ``now`` [s]; leave the wait or fault on none."""
        shared = self.core_state
        if not self.robot.measured:
            if self.robot.invalid_reason is not None:
                message = f'waiting for valid /joint_states: {self.robot.invalid_reason}'
                if message != shared.message:
                    shared.message, shared.changed = message, True
            return
        reason = self.robot.states_problem(now, shared.config.state_timeout)
        if reason is not None:
            if shared.state != sm.FAULT and sm.accepts(shared.state, sm.STATES_INVALID):
                if shared.state in sm.MOVING_STATES:
                    shared.result = {K.RESULT: MotionResult.FAULT, K.CAUSE: Cause.STATES_INVALID,
                                     K.REASON: reason}
                self.robot.drop_plan()
                shared.t_fault = now
                shared.step(sm.STATES_INVALID, 'ERROR', reason)
            return
        if shared.state == sm.WAITING_FOR_STATES:
            shared.step(sm.STATES_VALID, 'OK', 'joint states received; idle')
        elif shared.state == sm.FAULT and self.robot.t_states > shared.t_fault:
            shared.step(sm.STATES_VALID, 'OK', 'valid joint states again; idle')
