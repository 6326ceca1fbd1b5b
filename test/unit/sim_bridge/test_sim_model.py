"""The MuJoCo model built from the URDF: same kinematics as the core, plausible physics."""

from hypothesis import given, settings, strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import load_urdf, mover6
from mover6_control.kinematics.forward import fk, fk_frames
import mujoco
import numpy as np
import pytest
from sim_bridge.model import (build_mjcf, build_model, joint_dof_addresses, joint_qpos_addresses,
                              ModelOptions, site_transform)

ARMS = {name: mover6(name) for name in ('within_90_deg', 'hardware')}
MODELS = {name: build_model(arm) for name, arm in ARMS.items()}


def _mujoco_fk(model, arm, q):
    """Return MuJoCo's tip transform and joint frames for ``q``."""
    data = mujoco.MjData(model)
    data.qpos[joint_qpos_addresses(model, arm.joint_names)] = q
    mujoco.mj_kinematics(model, data)
    return site_transform(model, data, arm.tip_link), data


def _q_strategy(arm, margin=0.0):
    """Draw configurations inside the arm's limits widened by ``margin`` [rad]."""
    return st.tuples(*[st.floats(float(lo) - margin, float(hi) + margin)
                       for lo, hi in zip(arm.lower, arm.upper)]).map(np.array)


@pytest.mark.parametrize('limit_set', ['within_90_deg', 'hardware'])
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_fk_agrees_with_core(limit_set, data):
    """The MuJoCo tip pose equals the core's FK to 1e-9 on random configurations."""
    arm = ARMS[limit_set]
    q = data.draw(_q_strategy(arm, margin=0.5))
    T_mj, _ = _mujoco_fk(MODELS[limit_set], arm, q)
    np.testing.assert_allclose(T_mj, fk(arm, q), atol=1e-9, rtol=0)


def test_fk_home_is_the_mover6_report_flange_position():
    """At q = 0 MuJoCo puts the flange at (0.345, 0, 0.4425) m (the Mover6 report's URDF)."""
    arm = ARMS['within_90_deg']
    T_mj, _ = _mujoco_fk(MODELS['within_90_deg'], arm, np.zeros(6))
    np.testing.assert_allclose(T_mj[:3, 3], [0.345, 0.0, 0.4425], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(q=_q_strategy(ARMS['hardware']))
def test_joint_frames_and_world_axes_agree(q):
    """Every joint's anchor and world axis in MuJoCo equal the core's frames."""
    arm = ARMS['hardware']
    model = MODELS['hardware']
    _, data = _mujoco_fk(model, arm, q)
    frames = fk_frames(arm, q)
    for i, name in enumerate(arm.joint_names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        np.testing.assert_allclose(data.xanchor[jid], frames[i][:3, 3], atol=1e-9)
        np.testing.assert_allclose(data.xaxis[jid], frames[i][:3, :3] @ arm.axes[i], atol=1e-9)


@pytest.mark.parametrize('limit_set', ['within_90_deg', 'hardware'])
def test_ranges_are_the_joint_limits(limit_set):
    """Hinge ranges equal the arm's limits exactly and every joint is limited and actuated."""
    arm, model = ARMS[limit_set], MODELS[limit_set]
    for i, name in enumerate(arm.joint_names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE
        assert model.jnt_limited[jid]
        assert tuple(model.jnt_range[jid]) == (arm.lower[i], arm.upper[i])
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        assert aid >= 0 and model.actuator_trnid[aid, 0] == jid
        assert model.dof_damping[model.jnt_dofadr[jid]] > 0.0
    assert model.nu == arm.n_joints
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def test_masses_and_inertias_are_plausible():
    """Each moving body has positive mass and inertia; the arm weighs a few kilograms."""
    model = MODELS['within_90_deg']
    moving = range(1, model.nbody)
    masses = np.array([model.body_mass[b] for b in moving])
    assert np.all(masses > 0.05)
    assert 1.0 < masses.sum() < 6.0
    for b in moving:
        inertia = model.body_inertia[b]
        assert np.all(inertia > 0.0)
        # triangle inequality of principal moments: a physical rigid body
        assert inertia.sum() >= 2.0 * inertia.max() - 1e-12


def test_model_from_another_urdf(tmp_path):
    """The model follows whatever URDF it is given: fixed joints, rpy origins, other axes."""
    urdf = tmp_path / 'two.urdf'
    urdf.write_text("""<?xml version="1.0"?>
<robot name="two">
  <link name="base_link"/><link name="a"/><link name="b"/><link name="c"/><link name="tip"/>
  <joint name="ja" type="revolute"><parent link="base_link"/><child link="a"/>
    <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="1 1 0"/>
    <limit lower="-1" upper="2" velocity="1" effort="1"/></joint>
  <joint name="fix" type="fixed"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.25" rpy="0 0.5 0"/></joint>
  <joint name="jb" type="revolute"><parent link="b"/><child link="c"/>
    <origin xyz="0.05 0 0.1" rpy="0 0 0.7"/><axis xyz="0 0 -1"/>
    <limit lower="-2" upper="1" velocity="1" effort="1"/></joint>
  <joint name="tool" type="fixed"><parent link="c"/><child link="tip"/>
    <origin xyz="0 0.02 0.08" rpy="1.0 0 0"/></joint>
</robot>
""")
    arm = load_urdf(str(urdf), tip_link='tip')
    model = build_model(arm)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(arm.lower, arm.upper)
        T_mj, _ = _mujoco_fk(model, arm, q)
        np.testing.assert_allclose(T_mj, fk(arm, q), atol=1e-9, rtol=0)


def test_mjcf_is_text_with_the_names():
    """The MJCF names joints and actuators after the URDF joints and the site after the tip."""
    xml = build_mjcf(ARMS['within_90_deg'])
    for name in ARMS['within_90_deg'].joint_names:
        assert f'joint name="{name}"' in xml
        assert f'velocity name="{name}"' in xml
    assert 'site name="link6"' in xml
    assert 'timestep="0.002"' in xml


def test_gravity_is_compensated_at_rest():
    """With zero servo demand the arm holds its pose against gravity (drives hold the load)."""
    arm = ARMS['hardware']
    model = MODELS['hardware']
    data = mujoco.MjData(model)
    q0 = np.array([0.3, 0.8, -0.5, 0.4, 0.9, 0.0])
    data.qpos[joint_qpos_addresses(model, arm.joint_names)] = q0
    for _ in range(500):
        mujoco.mj_step(model, data)
    q = data.qpos[joint_qpos_addresses(model, arm.joint_names)]
    np.testing.assert_allclose(q, q0, atol=1e-9)
    effort = data.qfrc_actuator[joint_dof_addresses(model, arm.joint_names)]
    assert abs(effort[1]) > 0.5      # the shoulder carries the arm's weight


@pytest.mark.parametrize('bad', [{'physics_dt': 0.0}, {'physics_dt': 0.05},
                                 {'kv': -1.0}, {'damping': float('nan')},
                                 {'armature': -0.1}, {'linear_density': 0.0}])
def test_options_are_checked(bad):
    """Nonsense physical parameters are refused with a reason."""
    with pytest.raises(InvalidInputError):
        ModelOptions(**bad)


def test_physics_dt_reaches_the_model():
    """The physics step of the options is the model's timestep."""
    model = build_model(ARMS['within_90_deg'], ModelOptions(physics_dt=0.001))
    assert model.opt.timestep == 0.001
