"""The URDF tree's joint transforms against scipy's rotations, for every joint type it moves."""

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.urdf_tree import joint_transform, moving_transforms, parse_urdf
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

URDF = """<robot name="probe">
  <link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="turn" type="revolute">
    <parent link="base"/><child link="a"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.4 -0.5 0.6"/><axis xyz="1 2 2"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.05" rpy="1.2 0 -0.3"/><axis xyz="0 3 4"/>
  </joint>
  <joint name="follow" type="continuous">
    <parent link="b"/><child link="c"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <mimic joint="turn" multiplier="-2" offset="0.1"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="c"/><child link="d"/><origin xyz="0 0 0.1" rpy="0 1.5707963 0"/>
  </joint>
</robot>"""


def reference(xyz, rpy, rotation=None, shift=(0.0, 0.0, 0.0)):
    """``T`` of a URDF origin (rpy: fixed axes x, y, z) then a joint's rotation and shift."""
    T = np.eye(4)
    R0 = Rotation.from_euler('xyz', rpy).as_matrix()
    R = R0 if rotation is None else R0 @ rotation
    T[:3, :3] = R
    T[:3, 3] = np.asarray(xyz) + R0 @ np.asarray(shift)
    return T


@pytest.mark.parametrize('q', [0.0, 0.7, -2.5])
def test_joint_transforms_are_the_origin_then_the_joints_motion(q):
    tree = parse_urdf(URDF)
    got = {j.name: T for j, T in moving_transforms(tree, {'turn': q, 'slide': 0.3 * q})}
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    turn = reference([0.1, -0.2, 0.3], [0.4, -0.5, 0.6],
                     Rotation.from_rotvec(axis * q).as_matrix())
    assert np.abs(got['turn'] - turn).max() < 1e-12
    slide_axis = np.array([0.0, 0.6, 0.8])
    assert np.abs(got['slide'] - reference([0.0, 0.0, 0.05], [1.2, 0.0, -0.3],
                                           shift=slide_axis * 0.3 * q)).max() < 1e-12
    mimic = Rotation.from_rotvec([0.0, 0.0, -2.0 * q + 0.1]).as_matrix()
    follow = reference([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], mimic)
    assert np.abs(got['follow'] - follow).max() < 1e-12
    fixed = next(j for j in tree.joints if j.name == 'tool')
    assert np.abs(joint_transform(fixed) - reference([0, 0, 0.1], [0, 1.5707963, 0])).max() < 1e-12


def test_a_joint_not_given_is_left_out():
    tree = parse_urdf(URDF)
    assert [j.name for j, _ in moving_transforms(tree, {'slide': 0.1})] == ['slide']


def test_a_zero_axis_is_refused_with_the_joints_name():
    with pytest.raises(InvalidInputError, match='"turn" has an axis of zero length'):
        parse_urdf(URDF.replace('<axis xyz="1 2 2"/>', '<axis xyz="0 0 0"/>'))
