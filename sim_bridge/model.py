"""
The MuJoCo model of an arm, built from its ``ArmModel`` (and so from the URDF), never retyped.

Body i sits at the URDF origin of joint i (position and rotation copied to full precision), joint
i is a hinge on the URDF axis with the URDF limits as its range, and a site named after the tip
link sits at the arm's ``tool`` transform. MuJoCo's forward kinematics therefore equals the core's
``fk`` to rounding error.

The geoms are the collision geometry of ``mover6_control.collision.geometry`` (the link shapes
derived from the maker's meshes, the tool on the flange, the table plane, the base and any
keep-out boxes), the very shapes the collision checker uses: one model of the arm's volume, not
two. What URDF does not say is added
here, with values that are assumptions, not vendor data: masses of ``linear_density`` [kg/m]
times the link length plus ``joint_mass`` [kg] (about 3 kg for the Mover6, near the vendor's
stated weight of a few kilograms), shared by the geoms of each body, a reflected rotor inertia
``armature`` [kg m^2] and a viscous ``damping`` [N m s/rad] per joint. Every body carries gravity
compensation routed through the actuators, as the arm's own position-controlled drives hold
against gravity; ``effort`` then reads the whole motor torque including the gravity load.

Each joint is driven by a MuJoCo velocity servo, torque = kv (qd_cmd - qd), stiff as the
Mover6's worm-geared motors are. Integration is ``implicitfast``, which treats the servo's
damping implicitly, so a stiff servo is stable at a 1 to 2 ms step. The servo torque is not
limited: MuJoCo's implicit step linearises the servo and a clamped force makes it overshoot and
ring (measured here: unstable for kv >= 100 with a 100 N m clamp), so speed limits are enforced
on the command side (``Simulator``) instead.
Contacts exert no force (the physics' contact flag is off): the bridge stands in for the drives.
The geoms do collide for detection, which ``Simulator`` runs after every step to report contacts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mover6_control.collision.geometry import (body_shapes, build_geometry, CollisionGeometry,
                                               contact_xml, geom_xml, world_geoms_xml)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.parameters import SIM_BRIDGE   # the defaults
import mujoco
import numpy as np


@dataclass(frozen=True)
class ModelOptions:
    """Physical parameters the URDF does not give; units in brackets."""

    physics_dt: float = SIM_BRIDGE['physics_dt'].default   # [s]
    kv: float = SIM_BRIDGE['kv'].default         # velocity servo gain [N m s/rad]
    damping: float = SIM_BRIDGE['damping'].default   # joint viscous damping [N m s/rad]
    armature: float = 0.01           # reflected rotor inertia [kg m^2]
    linear_density: float = 2.5      # link mass per length [kg/m]
    joint_mass: float = 0.15         # mass of each joint's motor [kg]
    gravity: bool = True

    def __post_init__(self):
        """Check that every value is finite and positive where it must be."""
        for name in ('physics_dt', 'kv', 'linear_density'):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise InvalidInputError(f'{name} must be positive and finite, got {value}')
        for name in ('damping', 'armature', 'joint_mass'):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0.0:
                raise InvalidInputError(f'{name} must be >= 0 and finite, got {value}')
        if self.physics_dt > 0.01:
            raise InvalidInputError(f'physics_dt {self.physics_dt} s is too coarse (<= 0.01 s)')


def _num(x):
    """Return a float written with full precision (repr round-trips exactly)."""
    return repr(float(x))


def _vec(values):
    """Return a space-separated list of full-precision numbers."""
    return ' '.join(_num(v) for v in values)


def _quat(R):
    """Return the MuJoCo quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R, dtype=float).ravel())
    return quat


def _segment(p_end, axis):
    """Return the end point of a link capsule: the next origin, or a stub along the axis."""
    if np.linalg.norm(p_end) > 1e-6:
        return np.asarray(p_end, dtype=float)
    return 0.04 * np.asarray(axis, dtype=float)


def _body_geoms(geometry, body, mass):
    """Return the geoms of ``body`` sharing ``mass`` [kg] (an inertial when it has none)."""
    shapes = body_shapes(geometry, body)
    if not shapes:
        return [f'<inertial pos="0 0 0" mass="{_num(mass)}" diaginertia="1e-4 1e-4 1e-4"/>']
    each = _num(mass / len(shapes))
    return [geom_xml(s, f'mass="{each}" rgba="0.95 0.55 0.1 1"') for s in shapes]


def build_mjcf(arm: ArmModel, options: ModelOptions | None = None,
               geometry: CollisionGeometry | None = None) -> str:
    """
    Return the MJCF text (str) of ``arm`` (an ``ArmModel``) with ``options`` and ``geometry``.

    Names: joints and actuators carry the arm's joint names, bodies are ``<joint>_link``, the
    tool site is ``arm.tip_link``, geoms are the shapes' names (spaces as underscores). Ranges
    are the arm's limits; infinite limits leave a joint unlimited. ``geometry`` defaults to
    ``build_geometry(arm)`` (the default tool, no keep-out box).
    """
    opt = options or ModelOptions()
    geometry = build_geometry(arm) if geometry is None else geometry
    n = arm.n_joints
    gravity = '0 0 -9.81' if opt.gravity else '0 0 0'
    lines = [
        f'<mujoco model="{arm.name}">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_num(opt.physics_dt)}" integrator="implicitfast" '
        f'gravity="{gravity}">',
        '    <flag contact="disable"/>',
        '  </option>',
        '  <visual>',
        '    <global offwidth="1280" offheight="960"/>',
        '    <headlight ambient="0.35 0.35 0.35" diffuse="0.6 0.6 0.6" specular="0.1 0.1 0.1"/>',
        '  </visual>',
        '  <asset>',
        '    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.95 0.95 1" '
        'rgb2="0.65 0.72 0.8" width="64" height="64"/>',
        '  </asset>',
        '  <worldbody>',
        '    <light pos="0.5 -0.5 1.5" dir="-0.3 0.3 -1" directional="true"/>',
    ]
    lines += ['    ' + g for g in world_geoms_xml(geometry)]
    indent = '    '
    for i, joint in enumerate(arm.joint_names):
        origin = arm.origins[i]
        nxt = arm.origins[i + 1][:3, 3] if i + 1 < n else arm.tool[:3, 3]
        p_end = _segment(nxt, arm.axes[i])
        mass = opt.linear_density * float(np.linalg.norm(p_end)) + opt.joint_mass
        lines.append(f'{indent}<body name="{joint}_link" pos="{_vec(origin[:3, 3])}" '
                     f'quat="{_vec(_quat(origin[:3, :3]))}" gravcomp="1">')
        indent += '  '
        limited = bool(np.isfinite(arm.lower[i]) and np.isfinite(arm.upper[i]))
        rng = (f' range="{_num(arm.lower[i])} {_num(arm.upper[i])}" limited="true"'
               if limited else ' limited="false"')
        lines.append(f'{indent}<joint name="{joint}" type="hinge" axis="{_vec(arm.axes[i])}"'
                     f'{rng} damping="{_num(opt.damping)}" armature="{_num(opt.armature)}" '
                     'actuatorgravcomp="true"/>')
        lines += [indent + g for g in _body_geoms(geometry, i + 1, mass)]
    tool = arm.tool
    lines.append(f'{indent}<site name="{arm.tip_link}" pos="{_vec(tool[:3, 3])}" '
                 f'quat="{_vec(_quat(tool[:3, :3]))}" size="0.01" rgba="0.1 0.4 0.9 1"/>')
    for _ in range(n):
        indent = indent[:-2]
        lines.append(f'{indent}</body>')
    lines.append('  </worldbody>')
    lines += contact_xml(geometry, [f'{j}_link' for j in arm.joint_names])
    lines.append('  <actuator>')
    for joint in arm.joint_names:
        lines.append(f'    <velocity name="{joint}" joint="{joint}" kv="{_num(opt.kv)}"/>')
    lines.append('  </actuator>')
    lines.append('</mujoco>')
    return '\n'.join(lines) + '\n'


def build_model(arm: ArmModel, options: ModelOptions | None = None,
                geometry: CollisionGeometry | None = None) -> mujoco.MjModel:
    """Return a compiled ``mujoco.MjModel`` of ``arm``; see ``build_mjcf``."""
    return mujoco.MjModel.from_xml_string(build_mjcf(arm, options, geometry))


def joint_qpos_addresses(model: mujoco.MjModel,
                         joint_names: Sequence[str]) -> np.ndarray:
    """Return the qpos indices (n,) of the named hinge joints of a compiled ``model``."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in joint_names]
    missing = [name for name, i in zip(joint_names, ids) if i < 0]
    if missing:
        raise InvalidInputError(f'model has no joints {missing}')
    return np.array([model.jnt_qposadr[i] for i in ids])


def joint_dof_addresses(model: mujoco.MjModel,
                        joint_names: Sequence[str]) -> np.ndarray:
    """Return the dof (qvel) indices (n,) of the named hinge joints of a compiled ``model``."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in joint_names]
    missing = [name for name, i in zip(joint_names, ids) if i < 0]
    if missing:
        raise InvalidInputError(f'model has no joints {missing}')
    return np.array([model.jnt_dofadr[i] for i in ids])


def site_transform(model: mujoco.MjModel, data: mujoco.MjData,
                   site_name: str) -> np.ndarray:
    """Return the world transform (4, 4) of a site after ``mj_forward``/``mj_kinematics``."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name)
    if sid < 0:
        raise InvalidInputError(f'model has no site "{site_name}"')
    T = np.eye(4)
    T[:3, :3] = data.site_xmat[sid].reshape(3, 3)
    T[:3, 3] = data.site_xpos[sid]
    return T
