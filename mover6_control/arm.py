"""
The arm model: a serial chain of revolute joints with limits, loaded from URDF or DH.

A joint i sits at ``origins[i]`` (4, 4), the fixed transform from the previous joint's frame (the
base for joint 0) to joint i's frame at q = 0, and turns about ``axes[i]`` (3,), a unit vector in
its own frame. ``tool`` (4, 4) is the fixed transform from the last joint's frame to the tip link.
That is URDF's own description, so nothing is lost in translation; a DH table maps onto it too.
"""

from dataclasses import dataclass, replace
import os

from mover6_control.errors import InvalidInputError
import numpy as np
from scipy.spatial.transform import Rotation

CONFIG_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')


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
    def n_joints(self):
        """Return the number of joints."""
        return len(self.joint_names)

    def with_limits(self, lower=None, upper=None, velocity_limits=None):
        """Return a copy with other joint [rad] and/or velocity [rad/s] limits."""
        return replace(
            self,
            lower=self.lower if lower is None else lower,
            upper=self.upper if upper is None else upper,
            velocity_limits=self.velocity_limits if velocity_limits is None else velocity_limits)

    def check_q(self, q, name='q'):
        """Return ``q`` as a finite (n,) array or raise a helpful error."""
        q_arr = np.asarray(q, dtype=float)
        if q_arr.shape != (self.n_joints,):
            raise InvalidInputError(
                f'{name} must have shape ({self.n_joints},), got {q_arr.shape}')
        if not np.all(np.isfinite(q_arr)):
            raise InvalidInputError(f'{name} has non-finite values: {q_arr.tolist()}')
        return q_arr

    def within_limits(self, q, tol=1e-9):
        """Return True when every joint of ``q`` is inside its limits (with ``tol`` [rad])."""
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tol) & np.all(q <= self.upper + tol))

    def limit_violations(self, q, tol=1e-9):
        """Return a readable list of the joints of ``q`` that are outside their limits."""
        q = np.asarray(q, dtype=float)
        out = []
        for i, name in enumerate(self.joint_names):
            if q[i] < self.lower[i] - tol or q[i] > self.upper[i] + tol:
                out.append(f'{name}={q[i]:.4f} outside [{self.lower[i]:.4f}, {self.upper[i]:.4f}]')
        return out


def transform_from_xyz_rpy(xyz, rpy):
    """Return the 4x4 transform of a URDF origin: xyz [m], fixed-axis roll-pitch-yaw [rad]."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler('xyz', rpy).as_matrix()
    T[:3, 3] = xyz
    return T


def load_urdf(path, base_link='base_link', tip_link=None, name=None):
    """
    Load the revolute chain from ``base_link`` to ``tip_link`` of a URDF file.

    Fixed joints on the way are folded into the next joint's origin (or into ``tool``).
    ``tip_link`` defaults to the single leaf link of the tree. Only revolute (and continuous)
    joints are moving joints; any other moving type raises.
    """
    import yourdfpy  # local import: parsing is the only place that needs it

    if not os.path.isfile(path):
        raise InvalidInputError(f'URDF file not found: {path}')
    robot = yourdfpy.URDF.load(path, load_meshes=False, build_scene_graph=False,
                               build_collision_scene_graph=False)
    joints = robot.robot.joints
    by_child = {j.child: j for j in joints}
    links = {link.name for link in robot.robot.links}
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
    return ArmModel(name=name or robot.robot.name, joint_names=tuple(names),
                    origins=np.array(origins), axes=np.array(axes), tool=pending,
                    lower=np.array(lower), upper=np.array(upper),
                    velocity_limits=np.array(vel), base_link=base_link, tip_link=tip_link)


# The vendor's software limits and speeds (design.md, from CPRMover6.cpp / CPR_Mover6.xml).
MOVER6_HARDWARE_LIMITS_DEG = {
    'lower': [-130.0, -50.0, -110.0, -140.0, -70.0, -120.0],
    'upper': [130.0, 60.0, 75.0, 140.0, 60.0, 120.0],
    'velocity': [30.0, 30.0, 30.0, 30.0, 40.0, 100.0],
}
LIMIT_SETS = ('seed', 'hardware')


def mover6(limit_set='seed', urdf_path=None):
    """
    Return the Mover6 model from the shipped URDF.

    ``limit_set`` 'seed' keeps every joint in [-1.571, 1.571] rad as seed 000 does; 'hardware'
    uses the vendor's software limits. Velocity limits are the vendor's speeds in both.
    """
    arm = load_urdf(urdf_path or os.path.join(CONFIG_DIR, 'mover6.urdf'), tip_link='link6',
                    name='mover6')
    lim = MOVER6_HARDWARE_LIMITS_DEG
    velocity = np.radians(lim['velocity'])
    if limit_set == 'seed':
        return arm.with_limits(velocity_limits=velocity)
    if limit_set == 'hardware':
        return arm.with_limits(lower=np.radians(lim['lower']), upper=np.radians(lim['upper']),
                               velocity_limits=velocity)
    raise InvalidInputError(f'unknown limit set "{limit_set}", expected one of {LIMIT_SETS}')
