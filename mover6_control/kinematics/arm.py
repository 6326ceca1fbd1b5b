"""
The arm model: a serial chain of revolute joints with limits, loaded from URDF or DH.

A joint i sits at ``origins[i]`` (4, 4), the fixed transform from the previous joint's frame (the
base for joint 0) to joint i's frame at q = 0, and turns about ``axes[i]`` (3,), a unit vector in
its own frame. ``tool`` (4, 4) is the fixed transform from the last joint's frame to the tip link.
That is URDF's own description, so nothing is lost in translation; a DH table maps onto it too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
import os
import xml.etree.ElementTree as ElementTree

from mover6_control.errors import InvalidInputError
from mover6_control.parameters import LIMIT_SETS   # the limit sets mover6() takes
from mover6_control.resources import CONFIG_DIR
import numpy as np


@dataclass(frozen=True, eq=False)
class ArmModel:
    """A serial revolute arm: geometry, joint limits [rad] and velocity limits [rad/s]."""

    name: str
    joint_names: tuple
    origins: np.ndarray        # (n, 4, 4) parent joint frame -> joint frame at q = 0
    axes: np.ndarray           # (n, 3) unit joint axes in the joint frame
    tool: np.ndarray           # (4, 4) last joint frame -> tip link
    lower: np.ndarray          # (n,) [rad]
    upper: np.ndarray          # (n,) [rad]
    velocity_limits: np.ndarray  # (n,) [rad/s]
    base_link: str = 'base_link'
    tip_link: str = 'link6'

    def __post_init__(self):
        """Validate shapes and values, normalise axes, and freeze the arrays."""
        n = len(self.joint_names)
        if n == 0:
            raise InvalidInputError('an arm needs at least one joint')
        if len(set(self.joint_names)) != n:
            raise InvalidInputError(f'joint names repeat: {self.joint_names}')
        checks = {'origins': (n, 4, 4), 'axes': (n, 3), 'tool': (4, 4), 'lower': (n,),
                  'upper': (n,), 'velocity_limits': (n,)}
        for field, shape in checks.items():
            arr = np.array(getattr(self, field), dtype=float)
            if arr.shape != shape:
                raise InvalidInputError(f'{field} must have shape {shape}, got {arr.shape}')
            if field not in ('lower', 'upper') and not np.all(np.isfinite(arr)):
                raise InvalidInputError(f'{field} has non-finite values')
            if field == 'axes':
                norms = np.linalg.norm(arr, axis=1)
                if np.any(norms < 1e-9):
                    raise InvalidInputError(f'joint axis of zero length: {arr.tolist()}')
                arr = arr / norms[:, None]
            arr.setflags(write=False)
            object.__setattr__(self, field, arr)
        object.__setattr__(self, 'joint_names', tuple(self.joint_names))
        if np.any(np.isnan(self.lower)) or np.any(np.isnan(self.upper)):
            raise InvalidInputError('joint limits must not be NaN')
        if np.any(self.lower > self.upper):
            raise InvalidInputError(
                f'lower limit above upper limit: {self.lower.tolist()} > {self.upper.tolist()}')
        if np.any(self.velocity_limits <= 0.0):
            raise InvalidInputError(
                f'velocity limits must be positive, got {self.velocity_limits.tolist()}')

    @property
    def n_joints(self) -> int:
        """Return the number of joints."""
        return len(self.joint_names)

    def with_limits(self, lower: np.ndarray | None = None, upper: np.ndarray | None = None,
                    velocity_limits: np.ndarray | None = None) -> ArmModel:
        """Return a copy with other joint [rad] and/or velocity [rad/s] limits."""
        return replace(
            self,
            lower=self.lower if lower is None else lower,
            upper=self.upper if upper is None else upper,
            velocity_limits=self.velocity_limits if velocity_limits is None else velocity_limits)

    def check_q(self, q: np.ndarray, name: str = 'q') -> np.ndarray:
        """Return ``q`` as a finite (n,) array or raise a helpful error."""
        q_arr = np.asarray(q, dtype=float)
        if q_arr.shape != (self.n_joints,):
            raise InvalidInputError(
                f'{name} must have shape ({self.n_joints},), got {q_arr.shape}')
        if not np.all(np.isfinite(q_arr)):
            raise InvalidInputError(f'{name} has non-finite values: {q_arr.tolist()}')
        return q_arr

    def joint_index(self, name: str) -> int:
        """Return the index of joint ``name`` or raise naming the known joints."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise InvalidInputError(
                f'unknown joint "{name}" for {self.name}; joints are {list(self.joint_names)}'
            ) from None

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> bool:
        """Return True when every joint of ``q`` is inside its limits (with ``tol`` [rad])."""
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tol) & np.all(q <= self.upper + tol))

    def limit_violations(self, q: np.ndarray, tol: float = 1e-9) -> list[str]:
        """Return a readable list of the joints of ``q`` that are outside their limits."""
        q = np.asarray(q, dtype=float)
        out = []
        for i, name in enumerate(self.joint_names):
            if q[i] < self.lower[i] - tol or q[i] > self.upper[i] + tol:
                out.append(f'{name}={q[i]:.4f} outside [{self.lower[i]:.4f}, {self.upper[i]:.4f}]')
        return out


@dataclass(frozen=True)
class _UrdfLimit:
    """A joint's <limit>: each attribute a float, None where the file leaves it out."""

    lower: float | None
    upper: float | None
    velocity: float | None


@dataclass(frozen=True, eq=False)
class _UrdfJoint:
    """A joint of a URDF file as ``load_urdf`` reads it (origin None without <origin>)."""

    name: str
    type: str     # noqa: A003 - URDF's word
    parent: str
    child: str
    origin: np.ndarray | None
    axis: np.ndarray
    limit: _UrdfLimit | None


def _origin_matrix(element) -> np.ndarray | None:
    """
    Return the (4, 4) transform of an <origin> (``xyz``, ``rpy``: Rz(y) Ry(p) Rx(r)), or None.

    The operations are those of the URDF readers' common recipe (a translation times the static
    x-y-z Euler rotation), so the model's origins are the same numbers bit for bit.
    """
    if element is None:
        return None
    xyz = np.array(list(map(float, element.get('xyz', '0 0 0').split())))
    ai, aj, ak = np.array(list(map(float, element.get('rpy', '0 0 0').split())))
    si, sj, sk = np.sin(ai), np.sin(aj), np.sin(ak)
    ci, cj, ck = np.cos(ai), np.cos(aj), np.cos(ak)
    cc, cs = ci * ck, ci * sk
    sc, ss = si * ck, si * sk
    R = np.eye(4)
    R[0, 0], R[0, 1], R[0, 2] = cj * ck, sj * sc - cs, sj * cc + ss
    R[1, 0], R[1, 1], R[1, 2] = cj * sk, sj * ss + cc, sj * cs - sc
    R[2, 0], R[2, 1], R[2, 2] = -sj, cj * si, cj * ci
    T = np.identity(4)
    T[:3, 3] = xyz[:3]
    M = np.dot(np.dot(np.identity(4), T), R)
    M /= M[3, 3]
    return M


def _optional_float(text: str | None) -> float | None:
    """Return ``float(text)``, None for a missing attribute."""
    return float(text) if text is not None else None


def _read_urdf(path: str) -> tuple:
    """
    Return the robot's name, its link names and its joints (``_UrdfJoint``) of a URDF file.

    The standard library's XML reader: the arm needs only the <link> names and each <joint>'s
    type, parent, child, origin, axis and limit (the meshes and the scene are the console's).
    """
    try:
        robot = ElementTree.parse(path).getroot()
        joints = []
        for element in robot.findall('joint'):
            parent, child = element.find('parent'), element.find('child')
            if parent is None or child is None:
                raise InvalidInputError(
                    f'joint "{element.get("name")}" needs a parent and a child link in {path}')
            axis = element.find('axis')
            limit = element.find('limit')
            joints.append(_UrdfJoint(
                name=element.attrib['name'], type=element.get('type'),
                parent=parent.get('link'), child=child.get('link'),
                origin=_origin_matrix(element.find('origin')),
                axis=(np.array([1.0, 0, 0]) if axis is None
                      else np.array(list(map(float, axis.get('xyz', '1 0 0').split())))),
                limit=None if limit is None else _UrdfLimit(
                    lower=_optional_float(limit.get('lower')),
                    upper=_optional_float(limit.get('upper')),
                    velocity=_optional_float(limit.get('velocity')))))
        links = {link.get('name') for link in robot.findall('link')}
        return robot.attrib['name'], links, joints
    except ElementTree.ParseError as err:
        raise InvalidInputError(f'{path} is not XML: {err}') from None
    except (KeyError, ValueError) as err:
        raise InvalidInputError(f'{path} is not a readable URDF: {err!r}') from None


def load_urdf(path: str, base_link: str = 'base_link', tip_link: str | None = None,
              name: str | None = None) -> ArmModel:
    """
    Load the revolute chain from ``base_link`` to ``tip_link`` of a URDF file.

    Fixed joints on the way are folded into the next joint's origin (or into ``tool``).
    ``tip_link`` defaults to the single leaf link of the tree. Only revolute (and continuous)
    joints are moving joints; any other moving type raises.
    """
    if not os.path.isfile(path):
        raise InvalidInputError(f'URDF file not found: {path}')
    robot_name, links, joints = _read_urdf(path)
    by_child = {j.child: j for j in joints}
    if base_link not in links:
        raise InvalidInputError(f'base link "{base_link}" is not in {path}')
    if tip_link is None:
        parents = {j.parent for j in joints}
        leaves = sorted(links - parents)
        if len(leaves) != 1:
            raise InvalidInputError(f'URDF has leaves {leaves}: name the tip_link')
        tip_link = leaves[0]
    if tip_link not in links:
        raise InvalidInputError(f'tip link "{tip_link}" is not in {path}')
    chain = []
    link = tip_link
    while link != base_link:
        if link not in by_child:
            raise InvalidInputError(f'no chain from "{base_link}" to "{tip_link}" in {path}')
        joint = by_child[link]
        chain.append(joint)
        link = joint.parent
    chain.reverse()

    names, origins, axes, lower, upper, vel = [], [], [], [], [], []
    pending = np.eye(4)
    for joint in chain:
        origin = joint.origin if joint.origin is not None else np.eye(4)
        if joint.type == 'fixed':
            pending = pending @ origin
            continue
        if joint.type not in ('revolute', 'continuous'):
            raise InvalidInputError(f'joint "{joint.name}" is {joint.type}; only revolute arms')
        names.append(joint.name)
        origins.append(pending @ origin)
        pending = np.eye(4)
        axes.append(joint.axis if joint.axis is not None else [1.0, 0.0, 0.0])
        lim = joint.limit
        if joint.type == 'continuous' or lim is None or lim.lower is None:
            lower.append(-np.pi)
            upper.append(np.pi)
        else:
            lower.append(lim.lower)
            upper.append(lim.upper)
        vel.append(lim.velocity if lim is not None and lim.velocity else 1.0)
    return ArmModel(name=name or robot_name, joint_names=tuple(names),
                    origins=np.array(origins), axes=np.array(axes), tool=pending,
                    lower=np.array(lower), upper=np.array(upper),
                    velocity_limits=np.array(vel), base_link=base_link, tip_link=tip_link)


# The vendor's software limits and speeds (its driver's CPRMover6.cpp and CPR_Mover6.xml).
MOVER6_HARDWARE_LIMITS_DEG = {
    'lower': [-130.0, -50.0, -110.0, -140.0, -70.0, -120.0],
    'upper': [130.0, 60.0, 75.0, 140.0, 60.0, 120.0],
    'velocity': [30.0, 30.0, 30.0, 30.0, 40.0, 100.0],
}

# The vendor driver (cpr_robot, CPRMover6.cpp) moves whole encoder ticks once per cycle. One tick
# of each joint [rad] is 2 pi / (gear ratio * ticks per motor turn); the cycle is 50 ms (20 Hz).
# The controller's fraction_of_max mode and the simulator's vendor_driver mode both use these.
MOVER6_GEAR_RATIOS = (528.2, 528.2, 528.2, 499.1, 1.0, 1.0)
MOVER6_TICKS_PER_MOTOR_TURN = (1440, 1440, 1440, 1440, 1024, 1024)
MOVER6_TICK_SIZE = tuple(2.0 * np.pi / (gear * ticks) for gear, ticks in
                         zip(MOVER6_GEAR_RATIOS, MOVER6_TICKS_PER_MOTOR_TURN))
MOVER6_DRIVER_CYCLE = 0.05


def mover6(limit_set: str = 'within_90_deg', urdf_path: str | None = None) -> ArmModel:
    """
    Return the Mover6 model from the shipped URDF.

    ``limit_set`` 'within_90_deg' keeps every joint in [-1.571, 1.571] rad as the Mover6 report
    does; 'hardware'
    uses the vendor's software limits. Velocity limits are the vendor's speeds in both.
    """
    arm = load_urdf(urdf_path or os.path.join(CONFIG_DIR, 'mover6.urdf'), tip_link='link6',
                    name='mover6')
    lim = MOVER6_HARDWARE_LIMITS_DEG
    velocity = np.radians(lim['velocity'])
    if limit_set == 'within_90_deg':
        return arm.with_limits(velocity_limits=velocity)
    if limit_set == 'hardware':
        return arm.with_limits(lower=np.radians(lim['lower']), upper=np.radians(lim['upper']),
                               velocity_limits=velocity)
    raise InvalidInputError(f'unknown limit set "{limit_set}", expected one of {LIMIT_SETS}')


LENGTH_UNITS = {'m': 1.0, 'cm': 0.01, 'mm': 0.001}
ANGLE_UNITS = {'rad': 1.0, 'deg': np.pi / 180.0}


def _rot_z(theta):
    """Return the 4x4 rotation about z by ``theta`` [rad]."""
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def dh_link_transform(a: float, alpha: float, d: float) -> np.ndarray:
    """Return ``Tz(d) Tx(a) Rx(alpha)`` (4, 4), the fixed part of a standard DH row."""
    c, s = np.cos(alpha), np.sin(alpha)
    return np.array([[1.0, 0.0, 0.0, a],
                     [0.0, c, -s, 0.0],
                     [0.0, s, c, d],
                     [0.0, 0.0, 0.0, 1.0]])


def from_dh(a: Sequence[float], alpha: Sequence[float], d: Sequence[float],
            offset: Sequence[float] | None = None, *, length_unit: str = 'm',
            angle_unit: str = 'rad', lower: Sequence[float] | None = None,
            upper: Sequence[float] | None = None,
            velocity_limits: Sequence[float] | None = None, name: str = 'dh_arm',
            joint_names: Sequence[str] | None = None, base_link: str = 'base_link',
            tip_link: str | None = None, tool: np.ndarray | None = None) -> ArmModel:
    """
    Build an ``ArmModel`` from a standard (distal) Denavit-Hartenberg table.

    Row i is ``A_i = Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``, so joint i turns about
    the z axis of frame i - 1 and ``q = 0`` means the table's theta equals ``offset``.
    ``a`` and ``d`` are in ``length_unit`` ('m', 'cm' or 'mm'); ``alpha``, ``offset``, ``lower``
    and ``upper`` in ``angle_unit`` ('rad' or 'deg'); ``velocity_limits`` in ``angle_unit``
    per second. The model is always in metres and radians. Limits default to [-pi, pi] [rad]
    and velocity limits to 1 [rad/s]. ``tool`` (4, 4) [m] is an extra transform after the
    last DH frame.
    """
    if length_unit not in LENGTH_UNITS:
        raise InvalidInputError(
            f'unknown length unit "{length_unit}", expected one of {sorted(LENGTH_UNITS)}')
    if angle_unit not in ANGLE_UNITS:
        raise InvalidInputError(
            f'unknown angle unit "{angle_unit}", expected one of {sorted(ANGLE_UNITS)}')
    to_m, to_rad = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    columns = {}
    for key, value in (('a', a), ('alpha', alpha), ('d', d)):
        arr = np.asarray(value, dtype=float)
        if arr.ndim != 1 or arr.size == 0:
            raise InvalidInputError(f'DH column {key} must be a non-empty list, got {value!r}')
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError(f'DH column {key} has non-finite values: {arr.tolist()}')
        columns[key] = arr
    n = columns['a'].size
    if columns['alpha'].size != n or columns['d'].size != n:
        raise InvalidInputError(
            f'DH columns differ in length: a {n}, alpha {columns["alpha"].size}, '
            f'd {columns["d"].size}')

    def column(value, default, scale, key):
        arr = np.full(n, default, dtype=float) if value is None else np.asarray(
            value, dtype=float) * scale
        if arr.shape != (n,):
            raise InvalidInputError(f'{key} must have {n} values, got shape {arr.shape}')
        return arr

    offset = column(offset, 0.0, to_rad, 'offset')
    if not np.all(np.isfinite(offset)):
        raise InvalidInputError(f'DH offsets have non-finite values: {offset.tolist()}')
    lower = column(lower, -np.pi, to_rad, 'lower')
    upper = column(upper, np.pi, to_rad, 'upper')
    velocity_limits = column(velocity_limits, 1.0, to_rad, 'velocity_limits')
    links = [dh_link_transform(columns['a'][i] * to_m, columns['alpha'][i] * to_rad,
                               columns['d'][i] * to_m) for i in range(n)]
    origins = [_rot_z(offset[0])]
    for i in range(1, n):
        origins.append(links[i - 1] @ _rot_z(offset[i]))
    extra = np.eye(4) if tool is None else np.asarray(tool, dtype=float)
    if extra.shape != (4, 4):
        raise InvalidInputError(f'tool must have shape (4, 4), got {extra.shape}')
    joint_names = joint_names or tuple(f'joint{i + 1}' for i in range(n))
    if len(joint_names) != n:
        raise InvalidInputError(f'{len(joint_names)} joint names for {n} DH rows')
    return ArmModel(name=name, joint_names=tuple(joint_names), origins=np.array(origins),
                    axes=np.tile([0.0, 0.0, 1.0], (n, 1)), tool=links[-1] @ extra,
                    lower=lower, upper=upper, velocity_limits=velocity_limits,
                    base_link=base_link, tip_link=tip_link or f'link{n}')


DH_KEYS = ('name', 'length_unit', 'angle_unit', 'a', 'alpha', 'd', 'offset', 'lower', 'upper',
           'velocity_limits', 'joint_names', 'base_link', 'tip_link')


def load_dh_yaml(path: str) -> ArmModel:
    """
    Load an arm from a YAML DH table (keys as ``from_dh``'s arguments, see minibot_dh.yaml).

    Unknown keys raise, so a typo does not pass silently.
    """
    import yaml  # local import: only config loading needs it

    if not os.path.isfile(path):
        raise InvalidInputError(f'DH file not found: {path}')
    with open(path, encoding='utf-8') as stream:
        spec = yaml.safe_load(stream)
    if not isinstance(spec, dict):
        raise InvalidInputError(f'{path} must hold a mapping of DH keys')
    unknown = sorted(set(spec) - set(DH_KEYS))
    if unknown:
        raise InvalidInputError(f'{path}: unknown keys {unknown}, expected some of {DH_KEYS}')
    missing = [key for key in ('a', 'alpha', 'd') if key not in spec]
    if missing:
        raise InvalidInputError(f'{path}: missing DH columns {missing}')
    kwargs = {key: spec[key] for key in spec if key not in ('a', 'alpha', 'd', 'offset')}
    if 'joint_names' in kwargs:
        kwargs['joint_names'] = tuple(kwargs['joint_names'])
    return from_dh(spec['a'], spec['alpha'], spec['d'], spec.get('offset'), **kwargs)


def minibot(path: str | None = None) -> ArmModel:
    """Return the miniBOT report's NeXCOM miniBOT from its DH table (config/minibot_dh.yaml)."""
    return load_dh_yaml(path or os.path.join(CONFIG_DIR, 'minibot_dh.yaml'))
