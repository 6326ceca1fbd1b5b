"""
launch/moveit.launch.py needs only ROS's launch modules and the committed config/moveit/ files.

``ros2 launch`` runs it in a process with ``launch``, ``launch_ros``, ``ament_index_python`` and
PyYAML: none of the package's libraries (mujoco, numba, ruckig, scipy) may be imported, or a
machine with MoveIt but without those fails before the launch says anything. Its imports are
read from its syntax tree; then it is run in a fresh interpreter, and what that process imported
is checked. Without MoveIt it answers only its own message, before it reads any file; with MoveIt
(``moveit_installed`` made true) it starts ``move_group`` with every file of config/moveit/ and
the planning scene monitor's publishing flags.

``launch`` and ``launch_ros`` are not on PyPI, so where they are missing the file is run on
stand-ins that record what it builds (test doubles of ROS's classes, nothing of the file's);
where they are importable (a ROS 2 Jazzy install) the same checks run on the real ones too.
"""

import ast
import importlib.util
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

from mover6_control.resources import CONFIG_DIR
import pytest
import yaml

ROOT = os.path.dirname(CONFIG_DIR)
LAUNCH_FILE = os.path.join(ROOT, 'launch', 'moveit.launch.py')
MOVEIT = os.path.join(CONFIG_DIR, 'moveit')
ALLOWED_IMPORTS = {'launch', 'launch_ros', 'ament_index_python', 'yaml', 'os'}
# What the package's generator and checker pull in; none of it may reach ros2 launch.
HEAVY = ('mover6_control', 'sim_bridge', 'mujoco', 'numba', 'ruckig', 'scipy', 'numpy',
         'yourdfpy', 'rclpy')
REAL_LAUNCH = all(importlib.util.find_spec(m) is not None for m in ('launch', 'launch_ros'))
IMPLEMENTATIONS = ['stand-ins'] + (['ros-launch'] if REAL_LAUNCH else [])

STAND_INS = """
import sys, types


class Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration(Recorded):
    def perform(self, context):
        return context[self.args[0]]


names = {'launch': ['LaunchDescription'],
         'launch.actions': ['DeclareLaunchArgument', 'LogInfo', 'OpaqueFunction'],
         'launch.substitutions': [], 'launch_ros': [], 'launch_ros.actions': ['Node']}
for module, classes in names.items():
    sys.modules[module] = types.ModuleType(module)
    for name in classes:
        setattr(sys.modules[module], name, type(name, (Recorded,), {}))
sys.modules['launch.substitutions'].LaunchConfiguration = LaunchConfiguration
"""

# Run in a fresh interpreter: load the launch file, build its description, evaluate its start
# without MoveIt and with config/moveit/ made empty, print what it said and what was imported.
PROBE = """
import importlib.util, json, sys
if sys.argv[1] == 'stand-ins':
    exec(STAND_INS)
spec = importlib.util.spec_from_file_location('moveit_launch', sys.argv[2])
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
description = module.generate_launch_description()
module.MOVEIT_DIR = sys.argv[3]                 # an empty folder: nothing may be read from it
if sys.argv[1] == 'stand-ins':
    context = {'namespace': '', 'use_sim_time': 'false'}
    said = [action.kwargs['msg'] for action in module.start(context)]
else:
    from launch import LaunchContext
    from launch.utilities import perform_substitutions
    context = LaunchContext()
    context.launch_configurations.update({'namespace': '', 'use_sim_time': 'false'})
    said = [perform_substitutions(context, action.msg) for action in module.start(context)]
print(json.dumps({'said': said, 'modules': sorted(m.split('.')[0] for m in sys.modules)}))
"""


def imported_modules(path):
    """Return the top-level names of every module ``path`` imports, anywhere in the file."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {alias.name.split('.')[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, 'a relative import in a launch file'
            out.add(node.module.split('.')[0])
    return out


def test_the_launch_file_imports_only_launch_modules():
    assert imported_modules(LAUNCH_FILE) <= ALLOWED_IMPORTS


def test_the_check_sees_an_import_of_the_package(tmp_path):
    """The same reading finds the package's generator when a file imports it (in a function)."""
    path = tmp_path / 'x.launch.py'
    path.write_text('import os\n\n\ndef f():\n    from mover6_control.tools import '
                    'moveit_config\n    return moveit_config\n')
    assert imported_modules(str(path)) - ALLOWED_IMPORTS == {'mover6_control'}


@pytest.mark.parametrize('implementation', IMPLEMENTATIONS)
def test_without_moveit_it_says_so_first_and_imports_nothing_of_the_package(
        implementation, tmp_path):
    """Its own message, with config/moveit/ empty (no file read first), in a lean process."""
    probe = PROBE.replace('exec(STAND_INS)', f'exec({STAND_INS!r})')
    env = dict(os.environ)
    env.pop('PYTHONPATH', None)          # the source tree must not be needed either
    # ament_index_python looks for moveit_ros_move_group on this prefix path only: a prefix
    # without MoveIt, as on a machine where it is not installed.
    env['AMENT_PREFIX_PATH'] = str(tmp_path)
    done = subprocess.run([sys.executable, '-c', probe, implementation, LAUNCH_FILE,
                           str(tmp_path)], env=env, capture_output=True, text=True,
                          timeout=60, cwd=str(tmp_path))
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    (said,) = out['said']
    assert said.startswith('MoveIt is not installed (no package moveit_ros_move_group)')
    assert not set(HEAVY) & set(out['modules']), out['modules']


def stand_in_modules():
    """Return the stand-ins of launch and launch_ros (the same as the probe's)."""
    space = {}
    saved = dict(sys.modules)
    try:
        exec(STAND_INS, space)
        return {name: sys.modules[name] for name in
                ('launch', 'launch.actions', 'launch.substitutions', 'launch_ros',
                 'launch_ros.actions')}
    finally:
        for name in ('launch', 'launch.actions', 'launch.substitutions', 'launch_ros',
                     'launch_ros.actions'):
            if name in saved:
                sys.modules[name] = saved[name]
            else:
                sys.modules.pop(name, None)


@pytest.fixture(params=IMPLEMENTATIONS)
def launch_module(request):
    """Return the launch file loaded on stand-ins of launch, or on ROS's launch where it is."""
    with pytest.MonkeyPatch.context() as patch:
        if request.param == 'stand-ins':
            for name, module in stand_in_modules().items():
                patch.setitem(sys.modules, name, module)
        spec = importlib.util.spec_from_file_location('moveit_launch', LAUNCH_FILE)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.implementation = request.param
        yield module


def started_node(module, namespace):
    """Return (package, executable, namespace, parameters) of the node ``start`` returns."""
    if module.implementation == 'stand-ins':
        (node,) = module.start({'namespace': namespace, 'use_sim_time': 'true'})
        assert type(node).__name__ == 'Node'
        (parameters,) = node.kwargs['parameters']
        return (node.kwargs['package'], node.kwargs['executable'], node.kwargs['namespace'],
                parameters)
    # ROS's Node keeps its parameters in its own normalized form: its package, executable and
    # namespace are read from it, the parameters from the function start() passes them from.
    from launch import LaunchContext
    from launch_ros.actions import Node
    context = LaunchContext()
    context.launch_configurations.update({'namespace': namespace, 'use_sim_time': 'true'})
    (node,) = module.start(context)
    assert isinstance(node, Node)
    parameters = dict(module.move_group_parameters(), use_sim_time=True)
    return node.node_package, node.node_executable, namespace, parameters


def read(name):
    """Return the text of a file of config/moveit/."""
    with open(os.path.join(MOVEIT, name)) as f:
        return f.read()


def test_the_arguments_are_namespace_and_sim_time(launch_module):
    description = launch_module.generate_launch_description()
    if launch_module.implementation == 'stand-ins':
        entities = description.args[0]
        declared = [a.args[0] for a in entities if type(a).__name__ == 'DeclareLaunchArgument']
    else:
        entities = description.entities
        declared = [a.name for a in entities if type(a).__name__ == 'DeclareLaunchArgument']
    assert declared == ['namespace', 'use_sim_time']
    assert type(entities[-1]).__name__ == 'OpaqueFunction'


def test_with_moveit_move_group_gets_every_file_and_the_scene_flags(launch_module, monkeypatch):
    """move_group in the stack's namespace, with the files as committed and the scene published."""
    monkeypatch.setattr(launch_module, 'moveit_installed', lambda: True)
    package, executable, namespace, p = started_node(launch_module, 'arm2')
    assert (package, executable, namespace) == ('moveit_ros_move_group', 'move_group', 'arm2')
    assert p['robot_description'] == read('mover6_collision.urdf')
    assert ET.fromstring(p['robot_description']).findall('link/collision')
    assert p['robot_description_semantic'] == read('mover6.srdf')
    assert p['robot_description_kinematics'] == yaml.safe_load(read('kinematics.yaml'))
    planning = p['robot_description_planning']
    assert planning['joint_limits'] == yaml.safe_load(read('joint_limits.yaml'))['joint_limits']
    assert planning['cartesian_limits'] == yaml.safe_load(
        read('pilz_cartesian_limits.yaml'))['cartesian_limits']
    assert p['planning_pipelines'] == ['ompl', 'pilz_industrial_motion_planner']
    assert p['default_planning_pipeline'] == 'ompl'
    assert p['ompl'] == yaml.safe_load(read('ompl_planning.yaml'))
    assert p['pilz_industrial_motion_planner'] == yaml.safe_load(
        read('pilz_industrial_motion_planner_planning.yaml'))
    controllers = yaml.safe_load(read('moveit_controllers.yaml'))
    assert {k: p[k] for k in controllers} == controllers
    for flag in ('publish_planning_scene', 'publish_geometry_updates', 'publish_state_updates',
                 'publish_transforms_updates'):
        assert p[flag] is True, flag
    assert p['use_sim_time'] is True


def test_ompl_keeps_no_key_jazzy_does_not_read():
    """Humble's start_state_max_bounds_error is gone; the adapters are Jazzy's lists."""
    ompl = yaml.safe_load(read('ompl_planning.yaml'))
    assert 'start_state_max_bounds_error' not in ompl
    assert all(a.startswith('default_planning_request_adapters/')
               for a in ompl['request_adapters'])
    assert all(a.startswith('default_planning_response_adapters/')
               for a in ompl['response_adapters'])


def test_the_launch_file_is_installed_beside_config_moveit():
    """setup.py installs launch/ and config/moveit/ side by side, as MOVEIT_DIR expects."""
    with open(os.path.join(ROOT, 'setup.py')) as f:
        text = f.read()
    assert "glob('launch/*.launch.py')" in text and "glob('config/moveit/*')" in text
