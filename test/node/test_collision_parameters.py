"""
The planner's and the controller's collision parameters, refused where they collide the arm.

Real rclpy nodes in one process: the planner, the controller and a probe that publishes
/joint_states and sets the parameters through their parameter services, as ``ros2 param set``.
A keep-out wall 52 mm beside the arm, on either side, is refused at the parameter naming the
link and the depth; a box the arm is clear of is taken; a table margin the base's turntable is
in is refused; a wall given at start stops the node saying why.
"""

import os

from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.controller.node import ControllerNode
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.planner.node import PlannerNode
from mover6_control.parameters import PLANNER, SIM_BRIDGE
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from ros_testing import spin_until
from sensor_msgs.msg import JointState

pytestmark = pytest.mark.node
ARM = mover6()
NS = f'collision_parameters_{os.getpid()}'
HOME = np.asarray(SIM_BRIDGE['initial_q'].default)
# The keep-out walls of the Mover6's body check: 52 mm beside the arm, on either side.
WALLS = {'+y': [-0.5, 0.052, 0.14, 0.5, 0.5, 1.0], '-y': [-0.5, -0.5, 0.14, 0.5, -0.052, 1.0]}
# A fixture beside the table, clear of the arm where it stands.
HARMLESS = [0.3, 0.3, 0.0, 0.4, 0.4, 0.1]
NODES = ('planner', 'controller')


@pytest.fixture
def stack():
    """Return (executor, nodes by name, probe, parameter clients by name), all spinning."""
    context = rclpy.Context()
    rclpy.init(context=context)
    planner = PlannerNode(context=context, namespace=NS)
    controller = ControllerNode(context=context, namespace=NS,
                                parameter_overrides=[Parameter('tick_priority', value=0)])
    probe = Node('collision_probe', context=context, namespace=NS)
    states = probe.create_publisher(JointState, 'joint_states', 10)
    clients = {name: AsyncParameterClient(probe, name) for name in NODES}
    executor = SingleThreadedExecutor(context=context)
    for node in (planner, controller, probe):
        executor.add_node(node)
    nodes = {'planner': planner, 'controller': controller}
    assert spin_until(executor, lambda: all(c.services_are_ready() for c in clients.values()))

    def stand_at(q):
        """Publish /joint_states at ``q`` until both nodes hold them."""
        def held():
            states.publish(conversions.make_joint_state(ARM.joint_names, q, np.zeros(6)))
            return (planner.states.q is not None and np.allclose(planner.states.q, q)
                    and controller.last_q is not None and np.allclose(controller.last_q, q))
        assert spin_until(executor, held)
    yield executor, nodes, stand_at, clients
    executor.shutdown()
    for node in (planner, controller, probe):
        node.destroy_node()
    rclpy.try_shutdown(context=context)


def set_remotely(executor, client, name, value):
    """Set one parameter through the node's parameter service; return its SetParametersResult."""
    future = client.set_parameters([Parameter(name, value=value)])
    assert spin_until(executor, future.done), f'setting {name} not answered'
    return future.result().results[0]


@pytest.mark.parametrize('side', sorted(WALLS))
def test_a_wall_beside_the_arm_is_refused_naming_the_link_and_a_clear_box_is_taken(
        stack, side):
    """The wall 52 mm beside the arm where it stands: refused on both nodes, nothing changed."""
    executor, nodes, stand_at, clients = stack
    stand_at(HOME)
    for name in NODES:
        result = set_remotely(executor, clients[name], 'keep_out_boxes', WALLS[side])
        assert not result.successful, name
        assert 'keep_out_boxes puts the arm in collision where the arm stands' in result.reason
        link = result.reason.split(': ', 1)[1].split()[0]
        assert link in {f'link{i}' for i in range(1, 7)}, result.reason
        depth = float(result.reason.split(' is ')[1].split(' mm inside keep-out box 0')[0])
        assert depth > 1.0, result.reason
        assert list(nodes[name].get_parameter('keep_out_boxes').value) \
            == list(PLANNER['keep_out_boxes'].default)

        assert set_remotely(executor, clients[name], 'keep_out_boxes', HARMLESS).successful
        assert list(nodes[name].get_parameter('keep_out_boxes').value) == HARMLESS


def test_a_table_margin_the_arm_stands_in_is_refused_and_a_set_elsewhere_still_taken(stack):
    """A margin above link1's turntable: refused naming it; other parameters are untouched."""
    executor, nodes, stand_at, clients = stack
    stand_at(HOME)
    for name in NODES:
        result = set_remotely(executor, clients[name], 'table_margin', 0.2)
        assert not result.successful, name
        assert ('table_margin puts the arm in collision where the arm stands: link1 turntable '
                'is') in result.reason
        assert 'mm into the table margin (200.0 mm)' in result.reason
        assert nodes[name].get_parameter('table_margin').value \
            == PLANNER['table_margin'].default
        assert set_remotely(executor, clients[name], 'collision_step', 0.02).successful


def test_a_wall_the_arm_is_clear_of_where_it_stands_is_taken(stack):
    """Where it stands counts: the arm turned away from a wall in front of it takes the wall."""
    executor, nodes, stand_at, clients = stack
    front = [0.25, -0.5, 0.0, 0.5, 0.5, 1.0]
    stand_at(HOME)
    assert not set_remotely(executor, clients['planner'], 'keep_out_boxes', front).successful
    stand_at(np.array([-np.pi / 2, 0.0, 0.0, 0.0, 0.0, 0.0]) + HOME)
    assert set_remotely(executor, clients['planner'], 'keep_out_boxes', front).successful


@pytest.mark.parametrize('node_class', (PlannerNode, ControllerNode))
def test_a_wall_at_start_stops_the_node_naming_the_link(node_class):
    """At start, before any states, the start configuration is checked: the node does not start."""
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        with pytest.raises(ValueError, match=r'at the start configuration .*link\d .* mm inside'):
            node_class(context=context, namespace=NS + '_start', parameter_overrides=[
                Parameter('keep_out_boxes', value=WALLS['+y']),
                Parameter('tick_priority', value=0)])
    finally:
        rclpy.try_shutdown(context=context)
