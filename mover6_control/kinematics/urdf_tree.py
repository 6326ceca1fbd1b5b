"""
The whole joint tree of a URDF, as robot_state_publisher sees it: every joint's transform.

``ArmModel`` keeps only the chain the planner and controller need (base to tip, fixed joints
folded in). RViz needs every link: the state publisher (``nodes/state_publisher/node.py``) reads
the URDF text it publishes on ``/robot_description`` with ``parse_urdf`` and turns each
measured joint position into ``T_parent_child`` with ``joint_transform``, the fixed joints once
with ``fixed_transforms``. Parsed with the standard library's XML reader: a URDF's ``joint``,
``origin``, ``axis`` and ``mimic`` elements are all it needs.
"""

from __future__ import annotations

from dataclasses import dataclass
import xml.etree.ElementTree as ElementTree

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import euler_zyx_to_matrix, make_transform
import numpy as np

MOVING = ('revolute', 'continuous', 'prismatic')
KNOWN = MOVING + ('fixed', 'floating', 'planar')


@dataclass(frozen=True, eq=False)
class TreeJoint:
    """One URDF joint: parent -> child at ``origin`` (4, 4), moving about or along ``axis``."""

    name: str
    type: str     # noqa: A003 - URDF's word
    parent: str
    child: str
    origin: np.ndarray      # (4, 4) parent frame -> joint frame at zero
    axis: np.ndarray        # (3,) unit, in the joint frame
    mimic: str = ''         # joint this one follows: q = multiplier * q_mimic + offset
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True, eq=False)
class UrdfTree:
    """The robot's name, its root link and its joints (in file order)."""

    name: str
    root: str
    joints: tuple

    @property
    def moving(self) -> tuple:
        """Return the joints that move with a joint position (revolute, continuous, prismatic)."""
        return tuple(j for j in self.joints if j.type in MOVING)

    @property
    def fixed(self) -> tuple:
        """Return the fixed joints (published once, on /tf_static)."""
        return tuple(j for j in self.joints if j.type == 'fixed')


def _floats(text: str | None, default: tuple, what: str) -> np.ndarray:
    """Return the three numbers of a URDF attribute such as ``xyz="0 0 0.13"``."""
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        raise InvalidInputError(f'{what} must be three numbers, got "{text}"') from None
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise InvalidInputError(f'{what} must be three finite numbers, got "{text}"')
    return np.array(values)


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Return the rotation (3, 3) by ``angle`` [rad] about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def parse_urdf(text: str) -> UrdfTree:
    """
    Return the ``UrdfTree`` of URDF ``text``.

    Raises ``InvalidInputError`` for text that is not a URDF robot, a joint without parent or
    child, a link with two parents, a tree with no single root, or malformed numbers.
    """
    try:
        robot = ElementTree.fromstring(text)
    except ElementTree.ParseError as err:
        raise InvalidInputError(f'robot description is not XML: {err}') from None
    if robot.tag != 'robot':
        raise InvalidInputError(f'robot description must be a <robot>, got <{robot.tag}>')
    links = [link.get('name') for link in robot.findall('link')]
    joints = []
    parent_of = {}
    for element in robot.findall('joint'):
        name = element.get('name') or ''
        kind = element.get('type') or ''
        if kind not in KNOWN:
            raise InvalidInputError(f'joint "{name}" has unknown type "{kind}"')
        parent = element.find('parent')
        child = element.find('child')
        if parent is None or child is None or not parent.get('link') or not child.get('link'):
            raise InvalidInputError(f'joint "{name}" needs a parent and a child link')
        if child.get('link') in parent_of:
            raise InvalidInputError(f'link "{child.get("link")}" has two parents')
        parent_of[child.get('link')] = parent.get('link')
        origin = element.find('origin')
        xyz = _floats(origin.get('xyz') if origin is not None else None, (0, 0, 0),
                      f'joint "{name}" origin xyz')
        rpy = _floats(origin.get('rpy') if origin is not None else None, (0, 0, 0),
                      f'joint "{name}" origin rpy')
        axis_element = element.find('axis')
        axis = _floats(axis_element.get('xyz') if axis_element is not None else None,
                       (1, 0, 0), f'joint "{name}" axis')
        if kind in MOVING:
            norm = np.linalg.norm(axis)
            if norm < 1e-12:
                raise InvalidInputError(f'joint "{name}" has an axis of zero length')
            axis = axis / norm
        mimic = element.find('mimic')
        joints.append(TreeJoint(
            name=name, type=kind, parent=parent.get('link'), child=child.get('link'),
            # URDF's rpy is the rotation Rz(yaw) Ry(pitch) Rx(roll): ZYX Euler angles reversed.
            origin=make_transform(xyz, euler_zyx_to_matrix(rpy[2], rpy[1], rpy[0])), axis=axis,
            mimic=mimic.get('joint', '') if mimic is not None else '',
            multiplier=float(mimic.get('multiplier', 1.0)) if mimic is not None else 1.0,
            offset=float(mimic.get('offset', 0.0)) if mimic is not None else 0.0))
    roots = sorted({link for link in links if link not in parent_of})
    if len(roots) != 1:
        raise InvalidInputError(f'a URDF tree has one root link, this one has {roots}')
    return UrdfTree(name=robot.get('name', ''), root=roots[0], joints=tuple(joints))


def joint_transform(joint: TreeJoint, position: float = 0.0) -> np.ndarray:
    """Return ``T_parent_child`` (4, 4) of ``joint`` at ``position`` [rad or m]."""
    # No validation here: the origin and the unit axis were checked when the URDF was parsed,
    # and the state publisher calls this for every joint of every /tf it sends.
    if joint.type in ('revolute', 'continuous'):
        T = joint.origin.copy()
        T[:3, :3] = T[:3, :3] @ axis_rotation(joint.axis, position)
        return T
    if joint.type == 'prismatic':
        T = joint.origin.copy()
        T[:3, 3] += T[:3, :3] @ (joint.axis * position)
        return T
    return joint.origin


def moving_transforms(tree: UrdfTree, positions: dict) -> list:
    """
    Return ``[(joint, T_parent_child)]`` of the moving joints ``positions`` names (name -> value).

    A mimic joint follows its joint when that one is given. Joints not given are left out, as
    robot_state_publisher leaves them out.
    """
    out = []
    for joint in tree.moving:
        if joint.name in positions:
            value = positions[joint.name]
        elif joint.mimic and joint.mimic in positions:
            value = joint.multiplier * positions[joint.mimic] + joint.offset
        else:
            continue
        out.append((joint, joint_transform(joint, float(value))))
    return out


def fixed_transforms(tree: UrdfTree) -> list:
    """Return ``[(joint, T_parent_child)]`` of the fixed joints."""
    return [(joint, joint.origin) for joint in tree.fixed]
