"""
The Mover6 gripper as a ``control_msgs/action/GripperCommand`` server, and the digital inputs.

``GripperAction`` serves ``~/gripper_cmd`` (``/driver/gripper_cmd``) for the driver node: the
gripper hangs on joint 4's digital outputs (the vendor's ``CPRMover6.cpp``: bit 0 "Gripper open",
bit 1 "Gripper enabled"), so it is open or closed, nothing between, and it reports nothing back.
A goal whose ``command.position`` [m] is above half the stroke (``hardware.gripper.STROKE``)
opens it, one at or below closes it; ``max_effort`` has no meaning for it and is ignored. The
goal runs until the driver's estimate of the gap (``hardware.gripper.GripperModel``, also the
joint ``gripper`` in /joint_states) reaches the target, with feedback on the way; the result's
``position`` is that estimate, ``reached_goal`` whether it got there, ``effort`` 0 and
``stalled`` false (no force is measured). Refused with the reason: a position that is not a
finite number in [0, STROKE], a driver that sends nothing (``listen_only``); aborted: a link to
the adapter that is lost (the bits would go nowhere). A cancel ends the wait; the gripper keeps
its last command.

``InputPublisher`` publishes the arm's digital inputs (joint 1's module, "Digital in 1..3", as the
vendor's driver publishes ``/InputChannels``) on ``/InputChannels`` as ``std_msgs/UInt8MultiArray``
(one 0/1 per channel, the channels' names in the layout's label), at ``INPUT_RATE`` once the
module has answered.

Both run on the node's service node and executor (their callbacks wait): the node constructs
them with that node, its ``CallbackGuard`` (their callbacks go through it) and what they read of
the node, as functions: its ``ArmDriver`` and its lifecycle state. They read nothing else of it.
"""

import math
import threading
import time
from typing import Callable, Optional

from control_msgs.action import GripperCommand
from mover6_control.errors import InvalidInputError
from mover6_control.hardware import protocol
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.gripper import STROKE
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from std_msgs.msg import MultiArrayDimension, UInt8MultiArray

GRIPPER_FEEDBACK_PERIOD = 0.1
"""[s] between two feedback messages of a goal."""
SLACK = 1.0
"""[s] a goal may take beyond the estimated arrival before it is aborted."""
INPUT_RATE = 10.0
"""[Hz] /InputChannels."""


def gripper_command(position: float) -> str:
    """Return 'open' or 'closed' for a goal's ``position`` [m]; InvalidInputError if none fits."""
    if not isinstance(position, float) or not math.isfinite(position) or \
            not 0.0 <= position <= STROKE:
        raise InvalidInputError(f'gripper position must be a number in [0, {STROKE}] m (0 '
                                f'closed, {STROKE} open), got {position!r}')
    return 'open' if position > STROKE / 2 else 'closed'


class GripperAction:
    """The GripperCommand server of the driver node (module docstring)."""

    def __init__(self, server_node: Node, name: str, guard: CallbackGuard,
                 logger: RcutilsLogger, driver: Callable[[], Optional[ArmDriver]],
                 lifecycle_state: Callable[[], str]) -> None:
        """
        Serve the action ``name`` (the driver node's ~/gripper_cmd) on ``server_node``.

        Its callbacks go through ``guard``; ``driver()`` is the driver node's ``ArmDriver``
        (None while it is not configured) and ``lifecycle_state()`` the label of its state.
        """
        self.driver = driver
        self.lifecycle_state = lifecycle_state
        self.logger = logger
        self.group = ReentrantCallbackGroup()
        self.server = ActionServer(
            server_node, GripperCommand, name, self.execute, callback_group=self.group,
            **guard.action_callbacks(self.on_goal, lambda handle: CancelResponse.ACCEPT))

    def on_goal(self, goal: GripperCommand.Goal) -> GoalResponse:
        """Accept a goal the gripper can do; raise (the guard rejects it, with the reason)."""
        gripper_command(goal.command.position)
        state, driver = self.lifecycle_state(), self.driver()
        if state != 'active' or driver is None:
            raise InvalidInputError(f'gripper refused: the driver is {state}: activate it')
        if driver.listen_only:
            raise InvalidInputError('gripper refused: listen_only, the driver sends nothing')
        return GoalResponse.ACCEPT

    def execute(self, handle: ServerGoalHandle) -> GripperCommand.Result:
        """Drive the gripper and wait for the estimated gap to reach the target."""
        driver = self.driver()
        command = gripper_command(handle.request.command.position)
        result = GripperCommand.Result()
        if driver is None:                 # deactivated and cleaned up since the goal came
            handle.abort()
            return result
        report = driver.report
        if report is not None and report.link == 'lost':
            handle.abort()
            self.logger.warning('gripper: aborted, the link to the adapter is lost')
            return result
        deadline = time.monotonic() + driver.set_gripper(command) + SLACK
        wake = threading.Event()
        feedback = GripperCommand.Feedback()
        while True:
            gripper = driver.gripper.report(driver.clock())
            feedback.position = result.position = gripper.position
            result.reached_goal = feedback.reached_goal = not gripper.moving
            if handle.is_cancel_requested:
                handle.canceled()
                return result
            if not gripper.moving:
                break
            if time.monotonic() > deadline:
                handle.abort()
                return result
            handle.publish_feedback(feedback)
            wake.wait(GRIPPER_FEEDBACK_PERIOD)
        handle.succeed()
        self.logger.info(f'gripper: {command}, gap {result.position:.4f} m')
        return result

    def destroy(self) -> None:
        """Destroy the action server."""
        self.server.destroy()


class InputPublisher:
    """/InputChannels: the arm's digital inputs, from the driver's reports (module docstring)."""

    def __init__(self, node: Node, guard: CallbackGuard, server_node: Node,
                 driver: Callable[[], Optional[ArmDriver]]) -> None:
        """
        Publish on ``node`` from a timer of ``server_node`` (through ``guard``).

        ``driver()`` is the driver node's ``ArmDriver`` (None while it is not configured).
        """
        self.driver = driver
        self.publisher = node.create_publisher(UInt8MultiArray, '/InputChannels', 10)
        self.timer = guard.timer(1.0 / INPUT_RATE, self.publish, on=server_node,
                                 source='InputChannels')

    def publish(self) -> None:
        """Publish the inputs of the latest report, once joint 1's module has answered."""
        driver = self.driver()
        report = driver.report if driver is not None else None
        if report is None or not report.inputs:
            return
        msg = UInt8MultiArray()
        msg.layout.dim.append(MultiArrayDimension(
            label=','.join(protocol.INPUT_CHANNELS), size=len(report.inputs), stride=1))
        msg.data = [int(x) for x in report.inputs]
        self.publisher.publish(msg)
