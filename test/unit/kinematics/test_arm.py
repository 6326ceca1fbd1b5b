"""Arm models from URDF and DH tables: the shipped Mover6 and miniBOT, units and bad input."""

import os

from hypothesis import given, settings
from hypothesis import strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import (CONFIG_DIR, dh_link_transform, from_dh, load_dh_yaml,
                                           load_urdf, minibot, mover6)
from mover6_control.kinematics.forward import fk
import numpy as np
import pytest

MINIBOT_DH_MM = {'a': [27.5, 250.0, 70.0, 0.0, 0.0, 0.0],
                 'alpha': [np.pi / 2, 0.0, np.pi / 2, -np.pi / 2, np.pi / 2, 0.0],
                 'd': [339.0, 0.0, 0.0, 250.0, 0.0, 95.0]}


def _dh_product(a, alpha, d, offset, q):
    """Return prod_i Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i), written out directly."""
    T = np.eye(4)
    for ai, al, di, oi, qi in zip(a, alpha, d, offset, q):
        th = qi + oi
        ct, st_, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = T @ np.array([[ct, -st_ * ca, st_ * sa, ai * ct],
                          [st_, ct * ca, -ct * sa, ai * st_],
                          [0.0, sa, ca, di],
                          [0.0, 0.0, 0.0, 1.0]])
    return T


def test_minibot_config_is_the_minibot_report_table():
    arm = minibot()
    direct = from_dh(**MINIBOT_DH_MM, length_unit='mm', name='minibot')
    q = np.array([0.3, -0.4, 1.1, 0.2, -0.7, 2.0])
    np.testing.assert_allclose(fk(arm, q), fk(direct, q), atol=1e-12)
    assert arm.joint_names == tuple(f'joint{i}' for i in range(1, 7))
    assert arm.tip_link == 'end_effector'


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6),
       st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_from_dh_equals_the_dh_product(q, offset):
    arm = from_dh(MINIBOT_DH_MM['a'], MINIBOT_DH_MM['alpha'], MINIBOT_DH_MM['d'], offset,
                  length_unit='mm')
    a_m = np.array(MINIBOT_DH_MM['a']) / 1000.0
    d_m = np.array(MINIBOT_DH_MM['d']) / 1000.0
    expected = _dh_product(a_m, MINIBOT_DH_MM['alpha'], d_m, offset, q)
    np.testing.assert_allclose(fk(arm, q), expected, atol=1e-12)


def test_units_convert_lengths_angles_and_limits():
    deg = from_dh([100.0, 0.0], [90.0, 0.0], [0.0, 50.0], [10.0, 0.0], length_unit='cm',
                  angle_unit='deg', lower=[-90.0, -45.0], upper=[90.0, 45.0],
                  velocity_limits=[30.0, 60.0])
    rad = from_dh([1.0, 0.0], [np.pi / 2, 0.0], [0.0, 0.5], [np.radians(10.0), 0.0])
    q = np.array([0.4, -0.2])
    np.testing.assert_allclose(fk(deg, q), fk(rad, q), atol=1e-12)
    np.testing.assert_allclose(deg.upper, np.radians([90.0, 45.0]))
    np.testing.assert_allclose(deg.velocity_limits, np.radians([30.0, 60.0]))
    # q = 0 means theta = offset.
    np.testing.assert_allclose(fk(rad, [0.0, 0.0]),
                               _dh_product([1.0, 0.0], [np.pi / 2, 0.0], [0.0, 0.5],
                                           [np.radians(10.0), 0.0], [0.0, 0.0]), atol=1e-12)


def test_dh_link_transform_is_tz_tx_rx():
    T = dh_link_transform(0.2, np.pi / 2, 0.3)
    np.testing.assert_allclose(T @ [0.0, 1.0, 0.0, 1.0], [0.2, 0.0, 1.3, 1.0], atol=1e-12)


def test_mover6_urdf_and_limit_sets():
    arm = mover6()
    np.testing.assert_allclose(fk(arm, np.zeros(6))[:3, 3], [0.345, 0.0, 0.4425], atol=1e-12)
    np.testing.assert_allclose(arm.upper, 1.571)
    hw = mover6('hardware')
    np.testing.assert_allclose(np.degrees(hw.lower), [-130, -50, -110, -140, -70, -120])
    with pytest.raises(InvalidInputError, match='limit set'):
        mover6('factory')


@pytest.mark.parametrize('kwargs, match', [
    ({'a': [0.1, float('nan')], 'alpha': [0, 0], 'd': [0, 0]}, 'non-finite'),
    ({'a': [0.1, 0.2], 'alpha': [0], 'd': [0, 0]}, 'differ in length'),
    ({'a': [], 'alpha': [], 'd': []}, 'non-empty'),
    ({'a': [0.1], 'alpha': [0], 'd': [0], 'length_unit': 'inch'}, 'length unit'),
    ({'a': [0.1], 'alpha': [0], 'd': [0], 'angle_unit': 'grad'}, 'angle unit'),
    ({'a': [0.1], 'alpha': [0], 'd': [0], 'offset': [0, 1]}, 'offset'),
    ({'a': [0.1], 'alpha': [0], 'd': [0], 'lower': [1.0], 'upper': [0.0]}, 'lower limit'),
    ({'a': [0.1], 'alpha': [0], 'd': [0], 'joint_names': ('a', 'b')}, 'joint names'),
])
def test_bad_dh_tables_raise(kwargs, match):
    with pytest.raises(InvalidInputError, match=match):
        from_dh(**kwargs)


def test_dh_yaml_rejects_unknown_and_missing_keys(tmp_path):
    typo = tmp_path / 'typo.yaml'
    typo.write_text('a: [0.1]\nalpha: [0]\nd: [0]\nlenght_unit: mm\n')
    with pytest.raises(InvalidInputError, match='unknown keys'):
        load_dh_yaml(str(typo))
    missing = tmp_path / 'missing.yaml'
    missing.write_text('a: [0.1]\nalpha: [0]\n')
    with pytest.raises(InvalidInputError, match='missing DH columns'):
        load_dh_yaml(str(missing))
    with pytest.raises(InvalidInputError, match='not found'):
        load_dh_yaml(str(tmp_path / 'nope.yaml'))


def test_unknown_links_in_urdf_raise():
    path = os.path.join(CONFIG_DIR, 'mover6.urdf')
    with pytest.raises(InvalidInputError, match='tip link "flange"'):
        load_urdf(path, tip_link='flange')
    with pytest.raises(InvalidInputError, match='base link "world"'):
        load_urdf(path, base_link='world', tip_link='link6')


def test_joint_names_map_to_model_order():
    arm = mover6()
    assert arm.joint_index('joint5') == 4
    with pytest.raises(InvalidInputError, match='unknown joint "elbow"'):
        arm.joint_index('elbow')
