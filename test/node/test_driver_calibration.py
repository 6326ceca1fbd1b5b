"""
The driver node reads first_run's calibration file: a direction seen wrong refuses its start.

Real rclpy; the driver on python-can's ``virtual`` bus (nothing answers: the refusal comes
before the bus is opened).
"""

from dataclasses import replace
import os

from mover6_control.hardware.calibration import JointCalibration, write_calibration
from mover6_control.hardware.scaling import load_joints
from mover6_control.nodes.driver.node import DriverNode
import pytest
import rclpy
from rclpy.parameter import Parameter

_, JOINTS = load_joints()


@pytest.fixture
def context():
    """Yield an initialised rclpy context of its own."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def start(context, path):
    """Construct the driver node with ``calibration_file`` ``path``; return it."""
    return DriverNode(context=context, namespace=f'calibration_{os.getpid()}',
                      parameter_overrides=[
                          Parameter('can_interface', value='virtual'),
                          Parameter('can_channel', value=f'calibration_{os.getpid()}'),
                          Parameter('cycle_priority', value=0),
                          Parameter('calibration_file', value=path)])


def test_a_direction_seen_wrong_refuses_the_start_with_the_reason(context, tmp_path):
    joints = {j.name: JointCalibration(j.gear, True, True, 100, 5.0) for j in JOINTS}
    joints['joint2'] = replace(joints['joint2'], sign_confirmed=False)
    path = str(tmp_path / 'calibration.yaml')
    write_calibration(path, joints, 'now', 'config/mover6_joints.yaml')
    with pytest.raises(SystemExit, match='joint2: first_run saw it turn against'):
        start(context, path)


def test_a_confirmed_calibration_starts(context, tmp_path):
    joints = {j.name: JointCalibration(j.gear, True, True, 100, 5.0) for j in JOINTS}
    path = str(tmp_path / 'calibration.yaml')
    write_calibration(path, joints, 'now', 'config/mover6_joints.yaml')
    node = start(context, path)
    try:
        assert node.get_parameter('calibration_file').value == path
    finally:
        node.destroy_node()
