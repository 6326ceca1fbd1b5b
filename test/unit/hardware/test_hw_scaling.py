"""
Joint scaling of the Mover6, per joint, against figures worked out by hand from CPRMover6.cpp.

J1's gear is +528.2 with the URDF axis ``0 0 -1``, the vendor's own final pairing (its commit
d264510, "fixed rotation director for joint 0 of Mover6"); the ROS 2 port's -528.2 with axis
``0 0 1`` is the same arm, and a test below pins that both give the same flange pose.
"""

import copy
from dataclasses import replace
import math
import os

from hypothesis import given, strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.hardware.scaling import joints_from_dict, JOINTS_YAML, load_joints
from mover6_control.kinematics.arm import (mover6, MOVER6_GEAR_RATIOS,
                                           MOVER6_TICKS_PER_MOTOR_TURN)
from mover6_control.kinematics.forward import fk
from mover6_control.resources import CONFIG_DIR
import numpy as np
import pytest
import yaml

FIRMWARE, JOINTS = load_joints()
J1, J2, J3, J4, J5, J6 = JOINTS


def test_the_shipped_file():
    assert FIRMWARE == 'mover6'
    assert [j.name for j in JOINTS] == [f'joint{i}' for i in range(1, 7)]
    assert [j.module for j in JOINTS] == [1, 2, 3, 4, 5, 6]
    assert [j.gear for j in JOINTS] == [528.2, -528.2, 528.2, -499.1, 1.0, 1.0]
    assert [j.ticks_per_rev for j in JOINTS] == [1440, 1440, 1440, 1440, 1024, 1024]
    assert [j.offset for j in JOINTS] == [0, 0, 0, 0, 500, 509]


def test_agrees_with_the_arm_model():
    """The YAML's limits, speeds and gears are the kinematics' (one arm, not two)."""
    for name in ('hardware', 'within_90_deg'):
        arm = mover6(name)
        # The URDF writes pi/2 as 1.571: equal within its three decimals.
        assert np.allclose([j.limits[name][0] for j in JOINTS], arm.lower, rtol=0, atol=5e-4)
        assert np.allclose([j.limits[name][1] for j in JOINTS], arm.upper, rtol=0, atol=5e-4)
        assert np.allclose([j.max_speed for j in JOINTS], arm.velocity_limits)
    assert [abs(j.gear) for j in JOINTS] == list(MOVER6_GEAR_RATIOS)
    assert [j.ticks_per_rev for j in JOINTS] == list(MOVER6_TICKS_PER_MOTOR_TURN)


@pytest.mark.parametrize('joint,ticks', [(J1, 1440), (J2, -1440), (J3, 1440), (J4, -1440)])
def test_one_motor_turn_is_ticks_per_rev(joint, ticks):
    assert joint.to_ticks(2 * math.pi / abs(joint.gear)) == ticks
    assert joint.to_rad(ticks) == pytest.approx(2 * math.pi / abs(joint.gear))


def test_wrist_joints_and_their_offsets():
    assert J5.to_ticks(math.pi / 2) == 256 and J5.to_wire(256) == 756
    assert J6.to_ticks(-math.pi / 2) == -256 and J6.to_wire(-256) == 253
    assert J5.from_wire(500) == 0 and J6.from_wire(509) == 0
    assert math.degrees(J5.tick) == pytest.approx(0.3515625)
    assert J1.to_ticks(math.radians(1.0)) == 2113      # 2112.8 ticks per degree, rounded


def test_tick_limits_swap_for_a_negative_gear():
    assert J1.tick_limits('hardware') == (-274664, 274664)     # 130 deg x 2112.8
    assert J2.tick_limits('hardware') == (-126768, 105640)     # +60 deg -> -126768
    assert J3.tick_limits('hardware') == (-232408, 158460)
    assert J5.tick_limits('hardware') == (-199, 170)           # rounded inwards
    assert J1.tick_limits('within_90_deg') == (-190152, 190152)
    assert J2.tick_limits('within_90_deg') == J2.tick_limits('hardware')   # intersected


def test_clamping_in_ticks():
    assert J2.clamp_ticks(200000) == 105640
    assert J2.clamp_ticks(-200000) == -126768
    assert J2.clamp_ticks(1234) == 1234
    assert J5.clamp_ticks(171) == 170
    for joint in JOINTS:
        for limit_set in ('hardware', 'within_90_deg'):
            lo, hi = joint.limits_rad(limit_set)
            for ticks in joint.tick_limits(limit_set):
                assert lo - 1e-12 <= joint.to_rad(ticks) <= hi + 1e-12


@pytest.mark.parametrize('index', range(6))
@given(frac=st.floats(0.0, 1.0))
def test_round_trip_within_half_a_tick(index, frac):
    joint = JOINTS[index]
    lo, hi = joint.limits['hardware']
    q = lo + frac * (hi - lo)
    ticks = joint.to_ticks(q)
    assert abs(joint.to_rad(ticks) - q) <= joint.tick / 2 * (1 + 1e-9)
    assert joint.to_ticks(joint.to_rad(ticks)) == ticks


def test_non_finite_angle_is_refused():
    with pytest.raises(InvalidInputError, match='finite'):
        J1.to_ticks(float('nan'))
    with pytest.raises(InvalidInputError, match='limit_set'):
        J1.tick_limits('everything')


def _data():
    with open(JOINTS_YAML) as f:
        return yaml.safe_load(f)


@pytest.mark.parametrize('edit,match', [
    (lambda d: d['joints'][0].update(gear=0.0), 'gear must be non-zero'),
    (lambda d: d['joints'][0]['limits'].pop('hardware'), 'limits must map'),
    (lambda d: d['joints'][1]['limits'].update(hardware=[60.0, -50.0]), 'lower < upper'),
    (lambda d: d['joints'][1].update(module=1), 'modules must be 1..6'),
    (lambda d: d['joints'][2].update(name='joint1'), 'names must be unique'),
    (lambda d: d['joints'][3].update(offset=0.5), 'offset must be an integer'),
    (lambda d: d.update(firmware='mover4'), 'firmware must be one of'),
    (lambda d: d.update(joints=[]), 'non-empty list'),
    (lambda d: d['joints'][0].update(referencing={'required': 'yes'}), 'referencing must be'),
    (lambda d: d['joints'][0].update(referencing={'required': True, 'order': -1}),
     'referencing.order'),
    (lambda d: d['joints'][0].update(referencing={'required': True, 'speed': 1}),
     'referencing must be'),
])
def test_bad_joint_file_is_refused(edit, match):
    data = copy.deepcopy(_data())
    edit(data)
    with pytest.raises(InvalidInputError, match=match):
        joints_from_dict(data)
    assert joints_from_dict(_data())[1] == JOINTS


def test_referencing_j1_to_j4_in_order_the_wrist_needs_none():
    required = [(j.name, j.reference_order) for j in JOINTS if j.reference_required]
    assert required == [('joint1', 1), ('joint2', 2), ('joint3', 3), ('joint4', 4)]
    data = copy.deepcopy(_data())
    del data['joints'][0]['referencing']                     # absent: not required
    assert not joints_from_dict(data)[1][0].reference_required


def test_unreadable_file():
    with pytest.raises(InvalidInputError, match='cannot read'):
        load_joints('/no/such/file.yaml')


def _arm_with_joint1_axis(tmp_path, axis):
    """Return the Mover6 model with the URDF's joint 1 axis replaced by ``axis``."""
    text = open(os.path.join(CONFIG_DIR, 'mover6.urdf')).read()
    shipped = '<joint name="joint1" type="revolute">\n    <axis xyz="0 0 -1"/>'
    assert shipped in text
    path = tmp_path / 'mover6_joint1.urdf'
    path.write_text(text.replace(shipped, shipped.replace('0 0 -1', axis)))
    return mover6('hardware', str(path))


def test_j1_pairing_vendor_final_and_ros2_port_are_one_arm(tmp_path):
    """
    The same tick counts give the same flange pose with either pairing of J1's gear and axis.

    The vendor's final pair (+528.2, URDF axis 0 0 -1, ours) and the ROS 2 port's (-528.2, axis
    0 0 1) are the same physical arm; the pre-fix pair (-528.2, 0 0 -1) mirrors every pose off
    the x-z plane in y.
    """
    vendor = mover6('hardware')
    port = _arm_with_joint1_axis(tmp_path, '0 0 1')
    port_j1 = replace(J1, gear=-528.2)
    rng = np.random.default_rng(30)
    mirrored = 0
    for _ in range(50):
        q = rng.uniform(vendor.lower, vendor.upper) * 0.9
        ticks = [j.to_ticks(v) for j, v in zip(JOINTS, q)]
        q_vendor = np.array([j.to_rad(t) for j, t in zip(JOINTS, ticks)])
        q_port = q_vendor.copy()
        q_port[0] = port_j1.to_rad(ticks[0])
        assert np.allclose(fk(vendor, q_vendor), fk(port, q_port), atol=1e-12)
        # The pre-fix pairing reads the same ticks as the opposite angle of J1: with the arm
        # in its x-z plane at q1 = 0 (J4 at 0), the flange lands mirrored in y.
        q_vendor[3] = q_port[3] = 0.0
        T_prefix, T_vendor = fk(vendor, q_port), fk(vendor, q_vendor)
        assert np.allclose(T_prefix[:3, 3] * [1, -1, 1], T_vendor[:3, 3], atol=1e-9)
        mirrored += abs(T_vendor[1, 3]) > 1e-3
    assert mirrored > 40          # the random poses were off the x-z plane
