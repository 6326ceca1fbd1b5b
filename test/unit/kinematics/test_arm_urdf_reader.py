"""The arm's URDF reader against yourdfpy's: the same joints, origins equal bit for bit."""

import os

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import _read_urdf, CONFIG_DIR, load_urdf, mover6
import numpy as np
import pytest
import yourdfpy

SHIPPED = [os.path.join(CONFIG_DIR, 'mover6.urdf'),
           os.path.join(CONFIG_DIR, 'moveit', 'mover6_collision.urdf')]

# Every case the reader meets: defaults (no origin, no rpy, no axis, no limit, no velocity),
# a continuous joint, fixed joints folded in, angles that are not round numbers.
ODD = """<?xml version="1.0"?>
<robot name="odd">
  <!-- a comment -->
  <link name="base_link"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <link name="tip"/>
  <joint name="ja" type="revolute"><parent link="base_link"/><child link="a"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -1.2 2.9"/><axis xyz="1 1 0"/>
    <limit lower="-1" upper="2" effort="1"/></joint>
  <joint name="fix" type="fixed"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.25"/></joint>
  <joint name="jb" type="continuous"><parent link="b"/><child link="c"/>
    <origin rpy="0.1 0.2 0.7"/></joint>
  <joint name="jc" type="revolute"><parent link="c"/><child link="d"/>
    <axis xyz="0 0 -1"/><limit lower="-2.5" upper="1.25" velocity="0.75" effort="1"/></joint>
  <joint name="tool" type="fixed"><parent link="d"/><child link="tip"/>
    <origin xyz="0 0.02 0.08" rpy="1.0 0 -3.0"/></joint>
</robot>
"""


def urdf_files(tmp_path):
    """Return the shipped URDF files and the odd one."""
    odd = tmp_path / 'odd.urdf'
    odd.write_text(ODD)
    return SHIPPED + [str(odd)]


def test_joints_equal_yourdfpy_bit_for_bit(tmp_path):
    for path in urdf_files(tmp_path):
        name, links, joints = _read_urdf(path)
        ref = yourdfpy.URDF.load(path, load_meshes=False, build_scene_graph=False,
                                 build_collision_scene_graph=False).robot
        assert name == ref.name
        assert links == {link.name for link in ref.links}
        assert len(joints) == len(ref.joints) > 0
        for ours, theirs in zip(joints, ref.joints):
            assert (ours.name, ours.type, ours.parent, ours.child) == (
                theirs.name, theirs.type, theirs.parent, theirs.child)
            if theirs.origin is None:
                assert ours.origin is None
            else:
                np.testing.assert_array_equal(ours.origin, theirs.origin)
            np.testing.assert_array_equal(ours.axis, theirs.axis)
            if theirs.limit is None:
                assert ours.limit is None
            else:
                assert (ours.limit.lower, ours.limit.upper, ours.limit.velocity) == (
                    theirs.limit.lower, theirs.limit.upper, theirs.limit.velocity)


def test_the_odd_chain_folds_fixed_joints_and_takes_defaults(tmp_path):
    path = urdf_files(tmp_path)[-1]
    arm = load_urdf(path, tip_link='tip')
    assert arm.joint_names == ('ja', 'jb', 'jc')
    np.testing.assert_array_equal(arm.lower, [-1.0, -np.pi, -2.5])
    np.testing.assert_array_equal(arm.upper, [2.0, np.pi, 1.25])
    np.testing.assert_array_equal(arm.velocity_limits, [1.0, 1.0, 0.75])
    ref = yourdfpy.URDF.load(path, load_meshes=False, build_scene_graph=False,
                             build_collision_scene_graph=False).robot
    joint = {j.name: j for j in ref.joints}
    np.testing.assert_array_equal(arm.origins[0], joint['ja'].origin)
    np.testing.assert_array_equal(arm.origins[1], joint['fix'].origin @ joint['jb'].origin)
    np.testing.assert_array_equal(arm.origins[2], np.eye(4))
    np.testing.assert_array_equal(arm.tool, np.eye(4) @ joint['tool'].origin)


def test_the_mover6_model_is_unchanged():
    arm = mover6()
    assert arm.joint_names == tuple(f'joint{i}' for i in range(1, 7))
    assert arm.name == 'mover6'


@pytest.mark.parametrize('text, match', [
    ('<robot name="r"><link name="a"', 'not XML'),
    ('<robot><link name="a"/></robot>', 'not a readable URDF'),
    ('<robot name="r"><link name="base_link"/><joint name="j" type="fixed">'
     '<child link="base_link"/></joint></robot>', 'needs a parent and a child'),
    ('<robot name="r"><link name="base_link"/><link name="a"/><joint name="j" type="revolute">'
     '<parent link="base_link"/><child link="a"/><origin xyz="0 zero 0"/></joint></robot>',
     'not a readable URDF'),
])
def test_bad_files_raise_with_the_reason(tmp_path, text, match):
    path = tmp_path / 'bad.urdf'
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=match):
        load_urdf(str(path))
