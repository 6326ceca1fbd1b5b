"""
The arm's collision geometry: one description for the checker and for the simulator.

Every moving link is one or more shapes (a capsule or a flat-ended cylinder: a segment and a
radius) in the frame of the joint that moves it; the base is shapes in ``base_link``; a tool
volume (a capsule or a box, default a small gripper) sits on the flange; the table is the plane
z = 0 of ``base_link`` (the plane the arm stands on), kept ``table_margin`` away from; keep-out
zones are axis-aligned boxes in ``base_link``. ``geom_xml`` writes these same shapes as MuJoCo
geoms, which ``sim_bridge.model`` puts into the simulation model: the simulator and the checker
share one geometry.

The Mover6's shapes are ``body_model.BODY_SHAPES``, derived from its maker's meshes
(``body_fit``, ``tools.derive_collision``): every point of each link's mesh is at least
``body_fit.MARGIN`` inside its link's shapes, and housings are fitted along their own axes
(the shoulder and elbow along the joint-2 and joint-3 axes, the upper arm's side plate beside
the axis). Another arm gets capsules from each joint to the next, tapering from 40 to 20 mm.

Self-collision counts between links two or more apart in the chain (base, link1, ..., link6
with the tool); neighbours touch at their joint by construction and are never checked. The
table and the keep-out boxes are checked against every link, link1 included: the base and link1
(the world's geoms and its child's) are kept apart by MuJoCo's contact bits (``contact_bits``),
not by excluding the world.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mover6_control.collision import body_model
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.rotations import matrices_to_quaternions
from mover6_control.parameters import PLANNER, TOOL_SHAPES   # the defaults, the shapes
import numpy as np

TABLE = 'table'
BASE = 'base'
TOOL = 'tool'


@dataclass(frozen=True)
class ToolVolume:
    """
    The tool on the flange, in the flange (tip link) frame.

    ``shape`` is one of ``TOOL_SHAPES``; ``size`` is (width along x, depth along y, length along
    z) [m], the tool spanning z = 0 to length from the flange. A capsule has radius
    max(width, depth) / 2 and fills that length (its round ends included). Default: a small
    gripper, 60 mm across and 80 mm long.
    """

    shape: str = PLANNER['tool_shape'].default
    size: tuple = PLANNER['tool_size'].default

    def __post_init__(self):
        """Check the shape and the size."""
        if self.shape not in TOOL_SHAPES:
            raise InvalidInputError(f'tool shape must be one of {TOOL_SHAPES}, got {self.shape!r}')
        size = tuple(float(v) for v in self.size)
        if len(size) != 3 or not all(np.isfinite(v) and v > 0.0 for v in size):
            raise InvalidInputError(f'tool size must be 3 positive values [m], got {self.size}')
        if self.shape == 'capsule' and size[2] < max(size[0], size[1]):
            raise InvalidInputError(f'a capsule tool must be at least as long as it is wide, '
                                    f'got {size}')
        object.__setattr__(self, 'size', size)


@dataclass(frozen=True)
class Capsule:
    """A segment ``p0``-``p1`` [m] in the frame of ``body`` swollen by ``radius`` [m]."""

    name: str
    body: int            # 0: base_link; i: the frame of joint i (1-based)
    p0: tuple
    p1: tuple
    radius: float


@dataclass(frozen=True)
class Cylinder:
    """A flat-ended cylinder: the segment ``p0``-``p1`` [m] of ``body``'s frame, ``radius``."""

    name: str
    body: int
    p0: tuple
    p1: tuple
    radius: float


@dataclass(frozen=True)
class Box:
    """A box of half sizes ``half`` [m] centred at ``center`` in the frame of ``body``."""

    name: str
    body: int
    center: tuple
    half: tuple
    rotation: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class KeepOutBox:
    """A keep-out zone: an axis-aligned box in ``base_link`` from ``lower`` to ``upper`` [m]."""

    name: str
    lower: tuple
    upper: tuple


def keep_out_boxes(flat) -> tuple:
    """
    Return ``KeepOutBox``es from a flat list, 6 values per box: x, y, z min then x, y, z max.

    A box without volume (a max equal to its min, e.g. the all-zero default) is no box and is
    skipped, so a parameter that must not be empty can say "none". A max below its min is
    refused (min and max swapped would otherwise silently leave the zone unguarded).
    """
    values = np.asarray(list(flat), dtype=float).ravel()
    if values.size % 6:
        raise InvalidInputError(f'keep-out boxes need 6 values each (x y z min, x y z max), '
                                f'got {values.size} values')
    if not np.all(np.isfinite(values)):
        raise InvalidInputError('keep-out boxes must be finite')
    boxes = []
    for k, row in enumerate(values.reshape(-1, 6)):
        inverted = [axis for axis, lo, hi in zip('xyz', row[:3], row[3:]) if hi < lo]
        if inverted:
            raise InvalidInputError(
                f'keep-out box {k}: {", ".join(inverted)} max below its min ({row[:3].tolist()} '
                f'to {row[3:].tolist()}); give x, y, z min then x, y, z max')
        if np.all(row[3:] > row[:3]):
            boxes.append(KeepOutBox(f'keep-out box {k}', tuple(row[:3]), tuple(row[3:])))
    return tuple(boxes)


@dataclass(frozen=True)
class CollisionGeometry:
    """
    Everything the checker and the simulator collide: link capsules, tool, table, keep-out.

    ``capsules`` hold the shapes (``Capsule`` or ``Cylinder``) of the base and the links
    (bodies 0..n), ``tool`` the tool (a ``Capsule``, a ``Box`` or None, on body n),
    ``keep_out`` the zones, ``table_margin`` [m] the clearance kept above the table.
    ``body_names`` name bodies 0..n (base, link1 ..). ``excluded`` are the (i, j) body pairs
    left out of self-collision because they can never meet (``body_pairs``).
    """

    arm: ArmModel = field(repr=False)
    capsules: tuple
    tool: object
    table_margin: float
    keep_out: tuple
    body_names: tuple
    excluded: tuple = ()

    @property
    def shapes(self) -> tuple:
        """Return every shape of the arm: the link capsules, then the tool."""
        return self.capsules + ((self.tool,) if self.tool is not None else ())

    def self_pairs(self) -> list:
        """Return (i, j) shape indices of ``shapes`` two or more bodies apart, not excluded."""
        shapes = self.shapes
        return [(i, j) for i in range(len(shapes)) for j in range(i + 1, len(shapes))
                if abs(shapes[i].body - shapes[j].body) >= 2
                and tuple(sorted((shapes[i].body, shapes[j].body))) not in self.excluded]


def _link_name(arm, body):
    return BASE if body == 0 else arm.joint_names[body - 1].replace('joint', 'link')


def _default_capsules(arm):
    n = arm.n_joints
    radii = np.linspace(0.04, 0.02, n)
    out = []
    for i in range(n):
        nxt = arm.origins[i + 1][:3, 3] if i + 1 < n else arm.tool[:3, 3]
        if np.linalg.norm(nxt) < 1e-6:
            continue     # a joint at the next one's origin (a wrist): the neighbours cover it
        out.append((i + 1, (0.0, 0.0, 0.0), tuple(float(v) for v in nxt), float(radii[i])))
    return out


def build_geometry(arm: ArmModel, tool: ToolVolume | None = None, table_margin: float = 0.02,
                   keep_out=(), body: tuple | None = None) -> CollisionGeometry:
    """
    Return the ``CollisionGeometry`` of ``arm`` with ``tool``, ``table_margin`` [m], keep-out.

    ``keep_out`` is a sequence of ``KeepOutBox`` or the flat list of ``keep_out_boxes``.
    The Mover6 (``arm.name == 'mover6'``) gets ``body_model.BODY_SHAPES`` (from its meshes) and
    leaves out ``body_model.EXCLUDED_PAIRS``, or ``body`` (shape rows, excluded pairs) when
    given (the derivation's own); another arm capsules from each joint to the next.
    """
    tool = ToolVolume() if tool is None else tool
    if not np.isfinite(table_margin) or table_margin < 0.0:
        raise InvalidInputError(f'table_margin must be >= 0 [m], got {table_margin}')
    if len(keep_out) and not isinstance(keep_out[0], KeepOutBox):
        keep_out = keep_out_boxes(keep_out)
    n = arm.n_joints
    names = tuple(_link_name(arm, b) for b in range(n + 1))
    excluded = ()
    if arm.name == 'mover6' and n == 6:
        rows, pairs = body or (body_model.BODY_SHAPES, body_model.EXCLUDED_PAIRS)
        kinds = {'capsule': Capsule, 'cylinder': Cylinder}
        capsules = [kinds[kind](name, b, tuple(p0), tuple(p1), float(r))
                    for name, b, kind, p0, p1, r in rows]
        excluded = tuple(tuple(sorted(p[:2])) for p in pairs)
    else:
        rows = _default_capsules(arm)
        top = max(float(arm.origins[0][2, 3]), 0.02)
        capsules = [Capsule(BASE, 0, (0.0, 0.0, 0.0), (0.0, 0.0, max(top - 0.05, 0.0)), 0.05)]
        capsules += [Capsule(names[b], b, tuple(p0), tuple(p1), float(r))
                     for b, p0, p1, r in rows]
    T = np.asarray(arm.tool, dtype=float)
    name = f'{names[n]} {TOOL}'
    width, depth, length = tool.size
    if tool.shape == 'capsule':
        r = 0.5 * max(width, depth)
        p0 = T[:3, :3] @ np.array([0.0, 0.0, r]) + T[:3, 3]
        p1 = T[:3, :3] @ np.array([0.0, 0.0, length - r]) + T[:3, 3]
        tool_shape = Capsule(name, n, tuple(p0), tuple(p1), r)
    elif tool.shape == 'box':
        center = T[:3, :3] @ np.array([0.0, 0.0, 0.5 * length]) + T[:3, 3]
        tool_shape = Box(name, n, tuple(center), (0.5 * width, 0.5 * depth, 0.5 * length),
                         tuple(tuple(row) for row in T[:3, :3]))
    else:
        tool_shape = None
    return CollisionGeometry(arm=arm, capsules=tuple(capsules), tool=tool_shape,
                             table_margin=float(table_margin), keep_out=tuple(keep_out),
                             body_names=names, excluded=excluded)


# --- MuJoCo -----------------------------------------------------------------------------------

def _num(x):
    return repr(float(x))


def _vec(values):
    return ' '.join(_num(v) for v in values)


def _quat(R):
    """Return the MuJoCo quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    x, y, z, w = matrices_to_quaternions(R)
    return np.array([w, x, y, z])


COLLIDES = 'contype="1" conaffinity="1"'     # the table and the keep-out boxes


def contact_bits(body: int) -> str:
    """
    Return the MJCF contact bits of a shape on ``body`` (0: the base).

    Two geoms collide when one's contype shares a bit with the other's conaffinity. The base
    (2, 2) and link1 (1, 1) share none, so they never collide (they touch at joint 1 by
    construction); every other link (1, 3) collides with both, and every link with the table
    and the keep-out boxes (1, 1). MuJoCo itself skips a body against its parent (the other
    neighbours) and the world's geoms against each other.
    """
    if body == 0:
        return 'contype="2" conaffinity="2"'
    if body == 1:
        return 'contype="1" conaffinity="1"'
    return 'contype="1" conaffinity="3"'


def geom_xml(shape, attributes: str = '') -> str:
    """
    Return the MJCF ``<geom>`` of a ``Capsule``, ``Cylinder`` or ``Box`` in its body's frame.

    ``attributes`` is added as it is (mass, colour ...). Geoms collide with every geom but
    their neighbours' (``contact_bits``).
    """
    name = shape.name.replace(' ', '_')
    bits = contact_bits(shape.body) + (f' {attributes}' if attributes else '')
    if isinstance(shape, Cylinder):
        return (f'<geom name="{name}" type="cylinder" fromto="{_vec(shape.p0)} '
                f'{_vec(shape.p1)}" size="{_num(shape.radius)}" {bits}/>')
    if isinstance(shape, Capsule):
        p0, p1 = np.asarray(shape.p0), np.asarray(shape.p1)
        if np.linalg.norm(p1 - p0) < 1e-9:
            return (f'<geom name="{name}" type="sphere" pos="{_vec(p0)}" '
                    f'size="{_num(shape.radius)}" {bits}/>')
        return (f'<geom name="{name}" type="capsule" fromto="{_vec(p0)} {_vec(p1)}" '
                f'size="{_num(shape.radius)}" {bits}/>')
    return (f'<geom name="{name}" type="box" pos="{_vec(shape.center)}" '
            f'quat="{_vec(_quat(shape.rotation))}" size="{_vec(shape.half)}" {bits}/>')


def world_geoms_xml(geometry: CollisionGeometry, table_size: float = 1.0) -> list:
    """Return the MJCF geoms fixed to the world: table plane, base, keep-out boxes."""
    lines = [f'<geom name="{TABLE}" type="plane" size="{_num(table_size)} {_num(table_size)} '
             f'0.01" rgba="0.85 0.85 0.82 1" {COLLIDES}/>']
    lines += [geom_xml(s, 'rgba="0.3 0.3 0.3 1" mass="1"') for s in geometry.capsules
              if s.body == 0]
    for box in geometry.keep_out:
        lower, upper = np.asarray(box.lower), np.asarray(box.upper)
        lines.append(f'<geom name="{box.name.replace(" ", "_")}" type="box" '
                     f'pos="{_vec((lower + upper) / 2)}" size="{_vec((upper - lower) / 2)}" '
                     f'rgba="0.9 0.2 0.2 0.25" {COLLIDES}/>')
    return lines


def mjcf_excludes(geometry: CollisionGeometry, body_names) -> list:
    """
    Return the MJCF ``<exclude>`` lines of the pairs that can never meet (``excluded``).

    ``body_names`` are the MJCF names of bodies 1..n. The world is never excluded: the table
    and the keep-out boxes are checked against every link (``contact_bits`` keeps the base and
    link1 apart).
    """
    return [f'<exclude body1="{body_names[i - 1]}" body2="{body_names[j - 1]}"/>'
            for i, j in geometry.excluded if i > 0]


def contact_xml(geometry: CollisionGeometry, body_names) -> list:
    """Return the MJCF ``<contact>`` section of ``mjcf_excludes`` (none when it is empty)."""
    excludes = mjcf_excludes(geometry, body_names)
    return ['  <contact>'] + ['    ' + e for e in excludes] + ['  </contact>'] if excludes else []


def body_shapes(geometry: CollisionGeometry, body: int) -> list:
    """Return the shapes (link capsules and tool) on ``body`` (1..n)."""
    return [s for s in geometry.shapes if s.body == body]


def collision_mjcf(geometry: CollisionGeometry) -> str:
    """
    Return a MuJoCo model (MJCF text) of only the collision geometry: no mass, no actuators.

    Bodies carry the arm's joint names (``<joint>_link``), as in ``sim_bridge.model``; used to
    compare the checker with MuJoCo's own collision detection.
    """
    arm = geometry.arm
    lines = ['<mujoco model="collision">', '  <compiler angle="radian" autolimits="true"/>',
             '  <option gravity="0 0 0"/>', '  <worldbody>']
    lines += ['    ' + g for g in world_geoms_xml(geometry)]
    indent = '    '
    bodies = [f'{j}_link' for j in arm.joint_names]
    for i, joint in enumerate(arm.joint_names):
        origin = arm.origins[i]
        lines.append(f'{indent}<body name="{bodies[i]}" pos="{_vec(origin[:3, 3])}" '
                     f'quat="{_vec(_quat(origin[:3, :3]))}">')
        indent += '  '
        lines.append(f'{indent}<joint name="{joint}" type="hinge" axis="{_vec(arm.axes[i])}" '
                     'limited="false"/>')
        shapes = body_shapes(geometry, i + 1)
        lines += [indent + geom_xml(s, 'mass="0.1"') for s in shapes]
        if not shapes:
            lines.append(f'{indent}<inertial pos="0 0 0" mass="0.1" '
                         'diaginertia="1e-4 1e-4 1e-4"/>')
    for _ in arm.joint_names:
        indent = indent[:-2]
        lines.append(f'{indent}</body>')
    lines.append('  </worldbody>')
    lines += contact_xml(geometry, bodies)
    lines.append('</mujoco>')
    return '\n'.join(lines) + '\n'
