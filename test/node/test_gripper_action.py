"""
The gripper action and /InputChannels of the driver node, with real rclpy, on can_sim's arm.

The arm is ``sim_bridge.can_sim.BusServer`` (the CAN-level Mover6 with its gripper on joint 4's
outputs) on python-can's ``virtual`` bus in a thread of this process; the driver node drives it;
a client node sends ``control_msgs/action/GripperCommand`` goals to ``/driver/gripper_cmd`` and
reads /joint_states and /InputChannels.
"""

import itertools
import os
import threading
import time

import can
from control_msgs.action import GripperCommand
from mover6_control.hardware.gripper import STROKE
from mover6_control.nodes.driver.node import DriverNode
from mover6_control.realtime import steady_interpreter
import pytest
import rclpy
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.parameter import Parameter
from ros_testing import Spinning, wait_until
from sensor_msgs.msg import JointState
from sim_bridge.can_arm import GRIPPER_STROKE
from sim_bridge.can_sim import build_arm, BusServer
from std_msgs.msg import UInt8MultiArray

RUNS = itertools.count()


def wait_for(predicate, timeout=30.0):
    """Wait until ``predicate()`` is true; return whether it became true."""
    return wait_until(predicate, timeout, period=0.02)


class Operator(Node):
    """Send gripper goals; record /joint_states and /InputChannels."""

    def __init__(self, context, namespace):
        """Make the action client and the subscriptions."""
        super().__init__('operator', context=context, namespace=namespace)
        self.states, self.inputs, self.feedback = [], [], []
        self.create_subscription(JointState, 'joint_states', self.states.append, 10)
        self.create_subscription(UInt8MultiArray, '/InputChannels', self.inputs.append, 10)
        self.gripper = ActionClient(self, GripperCommand, 'driver/gripper_cmd')

    def send(self, position):
        """Send one goal; return (accepted, result or None)."""
        assert self.gripper.wait_for_server(timeout_sec=30.0)
        goal = GripperCommand.Goal()
        goal.command.position = float(position)
        sent = self.gripper.send_goal_async(goal, feedback_callback=self.feedback.append)
        assert wait_for(sent.done)
        handle = sent.result()
        if not handle.accepted:
            return False, None
        done = handle.get_result_async()
        assert wait_for(done.done)
        return True, done.result().result

    def gap(self):
        """Return the gripper joint in the latest /joint_states."""
        msg = self.states[-1]
        return msg.position[list(msg.name).index('gripper')]


@pytest.fixture
def rig():
    """Yield the driver node, the operator and the arm (on a virtual bus), the driver active."""
    channel = f'gripper_node_{os.getpid()}_{next(RUNS)}'
    namespace = f'gripper_test_{os.getpid()}_{next(RUNS)}'
    undo = steady_interpreter()                # as the driver's main() starts
    arm = build_arm()
    server = BusServer(arm, can.Bus(interface='virtual', channel=channel))
    stop = threading.Event()
    serving = threading.Thread(target=server.serve, args=(stop,), daemon=True)
    serving.start()
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = DriverNode(context=context, namespace=namespace, parameter_overrides=[
        Parameter('can_interface', value='virtual'), Parameter('can_channel', value=channel),
        Parameter('cycle_priority', value=0)])
    operator = Operator(context, namespace)
    spinning = Spinning(context, [driver, operator])      # each as its main() spins it
    try:
        # Configured at start; activated here: reset, enable, J1..J4 referenced.
        # The state machine's, not the node's own: that one reads 'inactive' while rcl is
        # still 'configuring', and an activation asked for then is not registered.
        assert wait_for(lambda: driver.machine_state == 'inactive')
        driver.trigger_activate()
        assert driver.lifecycle_state == 'active', driver.last_failure
        yield driver, operator, arm
    finally:
        spinning.close()
        driver.destroy_node()
        operator.destroy_node()
        rclpy.try_shutdown(context=context)
        stop.set()
        serving.join(timeout=10.0)
        server.bus.shutdown()
        undo()


def test_the_gripper_opens_and_closes_on_can_sim(rig):
    driver, operator, arm = rig
    assert wait_for(lambda: operator.states)
    assert operator.gap() == 0.0
    start = time.monotonic()
    accepted, result = operator.send(STROKE)
    took = time.monotonic() - start
    assert accepted and result.reached_goal and result.position == pytest.approx(STROKE)
    assert operator.feedback and 0.0 < operator.feedback[0].feedback.position < STROKE
    assert wait_for(lambda: arm.status()['gripper']['gap'] == GRIPPER_STROKE, 5.0)
    assert wait_for(lambda: operator.gap() == pytest.approx(STROKE), 5.0)
    accepted, result = operator.send(0.0)
    assert accepted and result.reached_goal and result.position == 0.0
    assert wait_for(lambda: arm.status()['gripper'] == {'gap': 0.0, 'command': 'closed'}, 5.0)
    assert wait_for(lambda: operator.gap() == 0.0, 5.0)
    print(f'FIGURE gripper: open goal answered in {took:.2f} s, closed again; '
          f'{len(operator.feedback)} feedback messages')


def test_a_gripper_goal_out_of_range_is_rejected(rig):
    driver, operator, arm = rig
    for position in (-0.01, STROKE * 2, float('nan')):
        accepted, _ = operator.send(position)
        assert not accepted
    assert arm.status()['gripper']['command'] == 'off'      # nothing changed


def test_the_digital_inputs_are_published(rig):
    driver, operator, arm = rig
    arm.set_inputs(0b011)
    assert wait_for(lambda: operator.inputs and list(operator.inputs[-1].data) == [1, 1, 0])
    assert operator.inputs[-1].layout.dim[0].label == 'Digital in 1,Digital in 2,Digital in 3'
