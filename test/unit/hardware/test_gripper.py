"""
The gripper and the digital inputs: the codec, the driver's estimate, the simulated gripper.

The bits are the vendor's (``CPRMover6.cpp``: joint 4's module, bit 0 "Gripper open", bit 1
"Gripper enabled"; joint 1's module, "Digital in 1..3" on bits 0..2). The driver drives the
CAN-level Mover6 (``CanArm`` behind ``BusServer``) on python-can's ``virtual`` bus in synthetic
time, as in test_driver_observability.py.
"""

import itertools

import can
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.gripper import GripperModel, STROKE, STROKE_TIME
from mover6_control.hardware.scaling import load_joints
import pytest
from sim_bridge.can_arm import GRIPPER_STROKE
from sim_bridge.can_sim import build_arm, BusServer

_, JOINTS = load_joints()
CYCLE = 0.05
CHANNELS = itertools.count()


def test_the_gripper_bits_are_joint_4s_bits_0_and_1():
    assert p.GRIPPER_JOINT == 4
    assert p.encode_gripper('open') == 0x03
    assert p.encode_gripper('closed') == 0x02
    assert p.encode_gripper('off', 0xFF) == 0xFC          # the other outputs kept
    assert p.encode_gripper('closed', 0x81) == 0x82
    assert [p.decode_gripper(b) for b in (0x00, 0x01, 0x02, 0x03, 0xFE)] == \
        ['off', 'off', 'closed', 'open', 'closed']
    with pytest.raises(p.ProtocolError, match='gripper command'):
        p.encode_gripper('half')
    with pytest.raises(p.ProtocolError, match='outputs'):
        p.decode_gripper(256)


def test_the_inputs_are_the_low_bits_of_a_replys_last_byte():
    assert p.decode_inputs(0x85) == (True, False, True)     # 0x80 is "referenced", no input
    assert p.decode_inputs(0x7F, 7) == (True,) * 7
    assert p.decode_reply(p.encode_reply(0, 0, 1, 0x82)).inputs == 0x82
    with pytest.raises(p.ProtocolError, match='channels'):
        p.decode_inputs(0, 8)


def test_the_model_estimates_the_gap_from_the_command_and_the_time():
    model = GripperModel()
    assert model.report(0.0).position == 0.0 and model.command == 'off'
    model.command_at('open', 1.0)
    assert model.arrival(1.0) == pytest.approx(STROKE_TIME)
    half = model.report(1.0 + STROKE_TIME / 2)
    assert half.position == pytest.approx(STROKE / 2) and half.moving and half.velocity > 0
    assert model.report(1.0 + STROKE_TIME).position == pytest.approx(STROKE)
    model.command_at('closed', 1.0 + STROKE_TIME / 2)          # closes from half way
    assert model.position(1.0 + STROKE_TIME * 3 / 4) == pytest.approx(STROKE / 4)
    model.command_at('off', 10.0)                               # not driven: stays where it is
    assert model.position(20.0) == 0.0 and not model.report(20.0).moving


class Bench:
    """The CAN-level arm and a driver on one virtual bus, in synthetic time."""

    def __init__(self):
        channel = f'gripper_{next(CHANNELS)}'
        self.t = 0.0
        self.arm = build_arm()
        self.buses = [can.Bus(interface='virtual', channel=channel) for _ in range(2)]
        self.server = BusServer(self.arm, self.buses[0], clock=lambda: self.t)
        self.driver = ArmDriver(self.buses[1], JOINTS, clock=lambda: self.t)

    def run(self, duration):
        """Run the driver's cycles for ``duration`` [s]."""
        for _ in range(int(round(duration / CYCLE))):
            self.driver.step(self.t)
            for _ in range(10):
                self.t += CYCLE / 10
                self.driver.send_due(self.t)
                self.server.poll(0.0)

    def close(self):
        """Close the driver and the arm's bus."""
        self.driver.close()
        self.buses[0].shutdown()


def test_the_simulated_gripper_opens_and_closes_on_the_drivers_bits():
    bench = Bench()
    try:
        bench.run(0.2)
        assert bench.arm.status()['gripper'] == {'gap': 0.0, 'command': 'off'}
        arrival = bench.driver.set_gripper('open')
        assert arrival == pytest.approx(STROKE_TIME)
        bench.run(CYCLE * 4)
        gap = bench.arm.status()['gripper']['gap']
        assert 0.0 < gap < GRIPPER_STROKE                 # on its way, over time
        assert bench.driver.report.gripper.moving
        bench.run(arrival)
        assert bench.arm.status()['gripper'] == {'gap': GRIPPER_STROKE, 'command': 'open'}
        assert bench.driver.report.gripper.position == pytest.approx(STROKE)
        assert bench.arm.modules[3].digital_out == 0x03
        bench.driver.set_gripper('closed')
        bench.run(STROKE_TIME + CYCLE * 2)
        assert bench.arm.status()['gripper'] == {'gap': 0.0, 'command': 'closed'}
        assert bench.driver.report.gripper.position == 0.0
        assert not bench.driver.report.gripper.moving
    finally:
        bench.close()


def test_the_digital_inputs_are_in_the_drivers_report():
    bench = Bench()
    try:
        assert bench.driver.step(bench.t).inputs == ()      # nothing heard yet
        bench.arm.set_inputs(0b101)
        bench.run(0.3)
        assert bench.driver.report.inputs == (True, False, True)
        bench.arm.set_inputs(0b010)
        bench.run(0.2)
        assert bench.driver.report.inputs == (False, True, False)
    finally:
        bench.close()
