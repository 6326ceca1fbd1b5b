"""
The MoveIt configuration (``config/moveit/``) checked statically against the package.

MoveIt is not installed here, so ``move_group`` never reads these files in this suite; what can be
checked without it is: the SRDF and the URDFs parse with the expected structure; every group,
chain, joint and link they name resolves in the URDF; the limits agree with the parameter table,
the driver's joint file and the kinematic model; the controller and its action resolve to the
controller node's server (under a namespace too: ``test/e2e/test_moveit_goals.py`` sends goals to
it there). That the generated files are the generator's output is
test/lint/test_generated_files.py's check; what the launch file passes,
test/unit/launch/test_moveit_launch.py's.
"""

import math
import os
import xml.etree.ElementTree as ET

from mover6_control.collision.checker import CollisionChecker
from mover6_control.control.timed_plan import START_TOLERANCE
from mover6_control.hardware.scaling import load_joints
from mover6_control.kinematics.arm import LIMIT_SETS, load_urdf, mover6
from mover6_control.node_roles import ESSENTIAL
from mover6_control.parameters import CONTROLLER, DRIVER, NODES, PLANNER
from mover6_control.resources import CONFIG_DIR
from mover6_control.tools import moveit_config
import numpy as np
import pytest
import yaml

MOVEIT = os.path.join(CONFIG_DIR, 'moveit')
URDF = os.path.join(CONFIG_DIR, 'mover6.urdf')
COLLISION_URDF = os.path.join(MOVEIT, 'mover6_collision.urdf')


def load(name):
    """Return a YAML file of config/moveit/ parsed."""
    with open(os.path.join(MOVEIT, name)) as f:
        return yaml.safe_load(f)


def urdf_chain(root, base, tip):
    """Return the joint names from ``base`` to ``tip`` in ``root`` (a URDF), walking by parent."""
    parent_of = {j.find('child').get('link'): j for j in root.findall('joint')}
    joints, link = [], tip
    while link != base:
        assert link in parent_of, f'{link} has no parent joint on the way to {base}'
        joint = parent_of[link]
        joints.append(joint.get('name'))
        link = joint.find('parent').get('link')
    return joints[::-1]


@pytest.fixture(scope='module')
def srdf():
    """Return the SRDF's root element."""
    return ET.parse(os.path.join(MOVEIT, 'mover6.srdf')).getroot()


@pytest.fixture(scope='module')
def urdf():
    """Return the root elements of the shipped URDF and of MoveIt's (with collision model)."""
    return ET.parse(URDF).getroot(), ET.parse(COLLISION_URDF).getroot()


def test_every_pipeline_and_hand_written_file_is_there():
    """The files move_group is started with (launch/moveit.launch.py) all exist and parse."""
    for name in ('kinematics.yaml', 'ompl_planning.yaml', 'pilz_cartesian_limits.yaml',
                 'pilz_industrial_motion_planner_planning.yaml', 'joint_limits.yaml',
                 'moveit_controllers.yaml'):
        assert isinstance(load(name), dict), name
    assert load('ompl_planning.yaml')['planning_plugins'] == ['ompl_interface/OMPLPlanner']
    pilz = load('pilz_industrial_motion_planner_planning.yaml')
    assert pilz['planning_plugins'] == ['pilz_industrial_motion_planner/CommandPlanner']
    assert pilz['default_planner_config'] == 'PTP'
    ompl = load('ompl_planning.yaml')
    group = ompl[moveit_config.GROUP]
    assert group['default_planner_config'] in group['planner_configs']
    assert set(group['planner_configs']) <= set(ompl['planner_configs'])
    limits = load('pilz_cartesian_limits.yaml')['cartesian_limits']
    assert limits['max_trans_vel'] > 0 and limits['max_trans_dec'] < 0


def test_srdf_structure(srdf, urdf):
    """One group, a chain base_link to the flange; named states; a virtual joint; same robot."""
    shipped, _ = urdf
    assert srdf.tag == 'robot' and srdf.get('name') == shipped.get('name')
    groups = srdf.findall('group')
    assert [g.get('name') for g in groups] == ['mover6_arm']
    chains = groups[0].findall('chain')
    assert len(chains) == 1 and len(list(groups[0])) == 1
    assert (chains[0].get('base_link'), chains[0].get('tip_link')) == ('base_link', 'link6')
    states = {s.get('name'): s for s in srdf.findall('group_state')}
    assert set(states) == {'home', 'ready'}
    assert all(s.get('group') == 'mover6_arm' for s in states.values())
    virtual = srdf.findall('virtual_joint')
    assert len(virtual) == 1 and virtual[0].get('child_link') == 'base_link'


def test_group_joints_and_links_resolve_in_both_urdfs(srdf, urdf):
    """The chain's joints are the arm's six in order, in the URDF, the model and the driver."""
    chain = srdf.find('group/chain')
    arm = mover6()
    _, joints = load_joints()
    for root in urdf:
        links = {link.get('name') for link in root.findall('link')}
        assert {chain.get('base_link'), chain.get('tip_link')} <= links
        assert urdf_chain(root, chain.get('base_link'), chain.get('tip_link')) == list(
            arm.joint_names) == [j.name for j in joints]
    # The tip link is the model's (the package's kinematics end at the same flange).
    assert arm.n_joints == 6 and np.allclose(arm.tool, np.eye(4))


def test_collision_urdf_is_the_shipped_kinematics(urdf):
    """The collision URDF has the shipped joints, axes and origins; a collision model a link."""
    shipped, moveit = urdf
    a, b = load_urdf(URDF, tip_link='link6'), load_urdf(COLLISION_URDF, tip_link='link6')
    assert a.joint_names == b.joint_names
    assert np.allclose(a.origins, b.origins) and np.allclose(a.axes, b.axes)
    assert np.allclose(a.tool, b.tool)
    assert [link.get('name') for link in shipped.findall('link')] == [
        link.get('name') for link in moveit.findall('link')]
    chain = {'base_link'} | {name.replace('joint', 'link') for name in a.joint_names}
    assert all(link.findall('collision') for link in moveit.findall('link')
               if link.get('name') in chain)     # the gripper's finger: no shape known
    assert not any(link.findall('collision') for link in shipped.findall('link'))


def test_named_states_resolve_within_every_limit_and_collision_free(srdf):
    """
    Both named states lie within every limit and collide with nothing; home is initial_q.

    Collisions by the package's checker, the table included.
    """
    arm_joints = list(mover6().joint_names)
    checker = CollisionChecker(mover6())
    limits = moveit_config.accepted_limits()
    for state in srdf.findall('group_state'):
        values = {j.get('name'): float(j.get('value')) for j in state.findall('joint')}
        assert sorted(values) == sorted(arm_joints) and len(state.findall('joint')) == 6
        q = np.array([values[name] for name in arm_joints])
        for name, v in values.items():
            assert limits[name][0] <= v <= limits[name][1], (state.get('name'), name)
        assert checker.check_configurations(q[None, :]).free, state.get('name')
    home = {j.get('name'): float(j.get('value')) for j in srdf.findall(
        "group_state[@name='home']/joint")}
    with open(os.path.join(CONFIG_DIR, 'sim_bridge.yaml')) as f:
        initial_q = yaml.safe_load(f)['/**/sim_bridge']['ros__parameters']['initial_q']
    assert [home[n] for n in arm_joints] == initial_q


def test_disabled_collisions_name_urdf_links_and_adjacent_is_parent_child(srdf, urdf):
    """Each pair names two URDF links, once; Adjacent: exactly the URDF's parent-child pairs."""
    shipped, _ = urdf
    links = {link.get('name') for link in shipped.findall('link')}
    pairs = [(d.get('link1'), d.get('link2'), d.get('reason'))
             for d in srdf.findall('disable_collisions')]
    keys = [frozenset(p[:2]) for p in pairs]
    assert len(set(keys)) == len(keys)
    assert all(a in links and b in links and a != b for a, b, _ in pairs)
    assert {why for _, _, why in pairs} <= {'Adjacent', 'Default', 'Always', 'Never'}
    parent_child = {frozenset((j.find('parent').get('link'), j.find('child').get('link')))
                    for j in shipped.findall('joint')}
    assert {frozenset((a, b)) for a, b, why in pairs if why == 'Adjacent'} == parent_child


def test_pairs_left_checked_do_collide_somewhere():
    """A pair MoveIt keeps checking collides at some sampled configuration (else: Never)."""
    arm = mover6()
    checker = CollisionChecker(arm)
    contacts = moveit_config.LinkContacts(checker, ('base_link',) + tuple(
        f'link{i}' for i in range(1, 7)))
    lower, upper = moveit_config.sampling_box()
    seen = set()
    for q in np.random.default_rng(1).uniform(lower, upper, size=(3000, 6)):
        seen |= contacts.pairs(q)
    with open(os.path.join(MOVEIT, 'mover6.srdf')) as f:
        root = ET.fromstring(f.read())
    never = {tuple(sorted((d.get('link1'), d.get('link2'))))
             for d in root.findall('disable_collisions') if d.get('reason') == 'Never'}
    assert not seen & never                        # another seed finds no Never pair colliding
    assert seen                                    # and the arm can hit itself
    # The pairs the collision model leaves out (they can never meet) are Never here too.
    names = ('base_link',) + tuple(f'link{i}' for i in range(1, 7))
    excluded = {tuple(sorted((names[i], names[j]))) for i, j in checker.geometry.excluded}
    assert excluded and excluded <= never


def test_joint_limits_come_from_the_driver_and_the_parameter_table(urdf):
    """
    Each joint's speed is the driver's max_speed; its acceleration the controller's a_max.

    The speed is also the model's and the shipped URDF's (to 1 mrad/s); one entry per joint.
    """
    limits = load('joint_limits.yaml')['joint_limits']
    _, joints = load_joints()
    arm = mover6()
    shipped, moveit = urdf
    urdf_speed = {j.get('name'): float(j.find('limit').get('velocity'))
                  for j in shipped.findall('joint')}
    assert list(limits) == [j.name for j in joints] == list(arm.joint_names)
    for joint, v_model in zip(joints, arm.velocity_limits):
        entry = limits[joint.name]
        assert entry['has_velocity_limits'] and entry['has_acceleration_limits']
        assert entry['max_velocity'] == joint.max_speed
        assert entry['max_velocity'] == pytest.approx(v_model, abs=1e-12)
        assert entry['max_velocity'] == pytest.approx(urdf_speed[joint.name], abs=1e-3)
        assert entry['max_acceleration'] == CONTROLLER['a_max'].default


def test_position_limits_are_what_every_layer_accepts(urdf):
    """
    The limits of MoveIt's URDF are every limit set of the driver's joint file at once.

    They lie within the controller's and the planner's default set and equal the intersection of
    the model's limit sets.
    """
    _, moveit = urdf
    _, joints = load_joints()
    given = {j.get('name'): (float(j.find('limit').get('lower')),
                             float(j.find('limit').get('upper'))) for j in moveit.findall('joint')}
    model = [mover6(name) for name in LIMIT_SETS]
    assert DRIVER['limit_set'].default in LIMIT_SETS
    for k, joint in enumerate(joints):
        lower, upper = given[joint.name]
        assert lower == max(lo for lo, _ in joint.limits.values())
        assert upper == min(hi for _, hi in joint.limits.values())
        assert lower == pytest.approx(max(a.lower[k] for a in model), abs=1e-3)
        assert upper == pytest.approx(min(a.upper[k] for a in model), abs=1e-3)
        for table in (CONTROLLER, PLANNER):
            default = mover6(table['limit_set'].default)
            assert default.lower[k] - 1e-3 <= lower < upper <= default.upper[k] + 1e-3


def test_controller_and_action_resolve_to_the_controller_node():
    """
    The controllers file names the controller node, its action and joints; relative names.

    Relative, so MoveIt's client resolves them in move_group's namespace (the stack's); MoveIt's
    start tolerance is the server's.
    """
    config = load('moveit_controllers.yaml')
    assert config['moveit_controller_manager'] == (
        'moveit_simple_controller_manager/MoveItSimpleControllerManager')
    manager = config['moveit_simple_controller_manager']
    assert manager['controller_names'] == ['controller']
    entry = manager['controller']
    assert entry['type'] == 'FollowJointTrajectory' and entry['default'] is True
    assert entry['action_ns'] == 'follow_joint_trajectory'
    assert entry['joints'] == list(mover6().joint_names)
    assert 'controller' in NODES and 'controller' in ESSENTIAL
    # Relative names: MoveIt's client resolves them in move_group's namespace.
    assert not entry['action_ns'].startswith('/') and not manager['controller_names'][0][0] == '/'
    execution = config['trajectory_execution']
    assert execution['allowed_start_tolerance'] == START_TOLERANCE
    assert math.isfinite(execution['allowed_execution_duration_scaling'])


def test_kinematics_names_the_group():
    """kinematics.yaml configures the group the SRDF defines."""
    config = load('kinematics.yaml')
    assert list(config) == [moveit_config.GROUP]
    assert config[moveit_config.GROUP]['kinematics_solver'].endswith('KDLKinematicsPlugin')
