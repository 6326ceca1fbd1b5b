"""
launch/mover6.launch.py and scripts/launch.sh start the same nodes with the same choices.

The launch file needs the ``launch`` and ``launch_ros`` packages, which this environment may not
have (launch_ros is not on PyPI), so it is read with ``ast``; launch.sh is read as text. Both
must start the same executables with the same parameter files, the same per-node overrides and
environment hooks, and offer the same choices (sim, hardware, profile, jog_units, limit_set)
with the same defaults, which are the package's own constants and the shipped parameter files'
values (the launch file takes those of profile, jog_units and limit_set from the controller's
parameter table, so they are read from the launch file executed on stand-ins). What the
``hardware`` argument starts is decided at launch time (an OpaqueFunction): the last test runs
the launch file on stand-ins that record what it builds, and calls that function for each
choice. What ``ros2 launch`` itself then does with the actions is not tested
here.
"""

import ast
import os
import re

from mover6_control.parameters import CONTROLLER, JOG_UNITS, LIMIT_SETS, PROFILES
from mover6_control.resources import CONFIG_DIR
import pytest
import yaml

ROOT = os.path.dirname(CONFIG_DIR)
LAUNCH_FILE = os.path.join(ROOT, 'launch', 'mover6.launch.py')
LAUNCH_SH = os.path.join(ROOT, 'scripts', 'launch.sh')
NODES = ('sim_bridge', 'driver', 'controller', 'planner', 'state_publisher', 'markers')
CHOICES = {'profile': PROFILES, 'jog_units': JOG_UNITS, 'limit_set': LIMIT_SETS}
# launch.sh's option and choice variable for each launch argument.
SH_NAMES = {'profile': ('--profile', 'PROFILES'), 'jog_units': ('--jog-units', 'JOG_UNITS'),
            'limit_set': ('--limit-set', 'LIMIT_SETS')}


def read(path):
    """Return the text of ``path``."""
    with open(path) as f:
        return f.read()


@pytest.fixture(scope='module')
def tree():
    """Return the launch file's syntax tree."""
    return ast.parse(read(LAUNCH_FILE), LAUNCH_FILE)


def calls(tree, name):
    """Return every call of function ``name`` in ``tree``."""
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call)
            and isinstance(n.func, ast.Name) and n.func.id == name]


def keyword(call, name):
    """Return the value node of keyword argument ``name`` of ``call`` (None when absent)."""
    return next((k.value for k in call.keywords if k.arg == name), None)


def launch_arguments(tree):
    """Return {name: DeclareLaunchArgument call} of the launch file's arguments named literally."""
    return {c.args[0].value: c for c in calls(tree, 'DeclareLaunchArgument')
            if isinstance(c.args[0], ast.Constant)}


def launch_nodes(tree):
    """Return {executable: Node call} of this package's nodes in the launch file."""
    out = {}
    for call in calls(tree, 'Node'):
        package = keyword(call, 'package')
        if isinstance(package, ast.Name) and package.id == 'PACKAGE':
            out[ast.literal_eval(keyword(call, 'executable'))] = call
    return out


def sh_starts():
    """Return {node: (executable, text of the rest of its start line)} from launch.sh."""
    text = read(LAUNCH_SH).replace('\\\n', ' ')
    return {m.group(1): (m.group(2), m.group(3))
            for m in re.finditer(r'^(?!\s*#).*\bstart (\w+) (\w+)(.*)$', text, re.MULTILINE)}


def sh_variable(name):
    """Return the value of a plain assignment ``name=value`` in launch.sh (quotes stripped)."""
    m = re.search(rf'^{name}=(.*)$', read(LAUNCH_SH), re.MULTILINE)
    assert m, f'launch.sh assigns no {name}'
    return m.group(1).strip('\'"')


def test_launch_file_compiles_and_defines_generate_launch_description(tree):
    compile(read(LAUNCH_FILE), LAUNCH_FILE, 'exec')
    functions = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert 'generate_launch_description' in functions


def test_launch_file_is_installed():
    assert "glob('launch/*.launch.py')" in read(os.path.join(ROOT, 'setup.py'))


def test_same_executables():
    starts = sh_starts()
    assert set(starts) == set(NODES)
    assert {exe for exe, _ in starts.values()} == set(launch_nodes(
        ast.parse(read(LAUNCH_FILE))))


def test_same_parameter_files(tree):
    """launch.sh passes config/<node>.yaml; the launch file's file argument defaults to it."""
    assert '"$share/$name.yaml"' in read(LAUNCH_SH)
    arguments = launch_arguments(tree)
    for exe, call in launch_nodes(tree).items():
        node = next(n for n, (e, _) in sh_starts().items() if e == exe)
        first = keyword(call, 'parameters').elts[0]
        assert ast.unparse(first) == f"LaunchConfiguration('{node}_params')"
        default = ast.unparse(keyword(arguments[f'{node}_params'], 'default_value'))
        assert default == f"config_file('{node}.yaml')"
        assert os.path.isfile(os.path.join(CONFIG_DIR, f'{node}.yaml'))


def test_same_overrides_and_environment_hooks(tree):
    """Every node gets the same parameter overrides and the same MOVER6_*_ARGS hook."""
    for exe, call in launch_nodes(tree).items():
        node = next(n for n, (e, _) in sh_starts().items() if e == exe)
        rest = sh_starts()[node][1]
        overrides = keyword(call, 'parameters').elts[1]
        assert sorted(ast.literal_eval(k) for k in overrides.keys) \
            == sorted(re.findall(r'-p "(\w+):=', rest)), node
        hooks = [ast.literal_eval(c.args[0]) for c in calls(keyword(call, 'ros_arguments'),
                                                            'extra_ros_args')]
        assert hooks == re.findall(r'\$\{(MOVER6_\w+_ARGS):-\}', rest), node


@pytest.mark.parametrize('name', CHOICES)
def test_same_choices_and_defaults(launch_module, name):
    """profile, jog_units, limit_set: the package's choices, the parameter files' defaults."""
    declared = declared_arguments(launch_module)[name]
    option, variable = SH_NAMES[name]
    choices = declared['choices']
    assert sorted(choices) == sorted(CHOICES[name])
    assert sorted(sh_variable(variable).split()) == sorted(CHOICES[name])
    assert f'{option})' in read(LAUNCH_SH)
    default = declared['default_value']
    assert default == sh_variable(name) == CONTROLLER[name].default
    # launch.sh --help (its leading comment) names every choice and the default.
    help_text = re.search(rf'^#   {option} .*?(?=^#   --)', read(LAUNCH_SH), re.M | re.S).group(0)
    assert [c for c in CHOICES[name] if not re.search(rf'\b{c}\b', help_text)] == []
    assert f'{default} (default' in help_text
    for node in NODES:
        if (node, name) == ('driver', 'limit_set'):
            continue      # alone it clamps to the vendor's limits; the stack passes its own
        values = yaml.safe_load(read(os.path.join(CONFIG_DIR, f'{node}.yaml')))
        value = values[f'/**/{node}']['ros__parameters'].get(name)
        assert value in (None, default), f'{node}.yaml has {name}: {value}, default {default}'


def test_same_sim_choice(tree):
    """sim:=true|false (default true) is launch.sh's --no-sim: only sim_bridge depends on it."""
    call = launch_arguments(tree)['sim']
    assert ast.literal_eval(keyword(call, 'choices')) == ['true', 'false']
    assert ast.literal_eval(keyword(call, 'default_value')) == 'true'
    assert sh_variable('with_sim') == '1'
    assert re.search(r'--no-sim\) with_sim=0', read(LAUNCH_SH))
    for exe, call in launch_nodes(tree).items():
        condition = keyword(call, 'condition')
        if exe == 'sim_bridge':
            assert ast.unparse(condition) == 'IfCondition(with_sim)'
        else:
            assert condition is None, exe
    guarded = re.findall(r'^\[ "\$with_sim" = 1 \] && start (\w+)', read(LAUNCH_SH), re.MULTILINE)
    assert guarded == ['sim_bridge']
    guarded = re.findall(r'^\[ "\$with_driver" = 1 \] && start (\w+)', read(LAUNCH_SH),
                         re.MULTILINE)
    assert guarded == ['driver']


def test_same_hardware_choice(tree, launch_module):
    """hardware:=sim|can_sim|can is launch.sh's --hardware sim|can-sim|can, default sim."""
    call = launch_arguments(tree)['hardware']
    choices = ast.literal_eval(keyword(call, 'choices'))
    assert [c.replace('_', '-') for c in choices] == sh_variable('HARDWARE').split()
    assert ast.literal_eval(keyword(call, 'default_value')) == sh_variable('hardware') == 'sim'
    assert ast.literal_eval(keyword(launch_arguments(tree)['can_interface'], 'default_value')) \
        == sh_variable('can_interface') == 'cpr_usb2can'
    for option in ('--hardware)', '--can-interface)', '--can-channel)'):
        assert option in read(LAUNCH_SH)
    # The controller's state timeout: the shipped file's on the simulator, 0.5 s on the driver.
    timeouts = launch_module.STATE_TIMEOUT
    controller = yaml.safe_load(read(os.path.join(CONFIG_DIR, 'controller.yaml')))
    shipped = controller['/**/controller']['ros__parameters']['state_timeout']
    assert float(timeouts['sim']) == shipped
    assert timeouts['can_sim'] == timeouts['can'] == '0.5'
    in_sh = re.findall(r'^    state_timeout=(.*)$', read(LAUNCH_SH), re.MULTILINE)
    assert sorted(float(v) for v in in_sh) == sorted((shipped, 0.5))


def test_robot_state_publisher_only_when_installed(tree):
    """robot_state_publisher is started from an OpaqueFunction that looks the package up."""
    function = next(n for n in tree.body
                    if isinstance(n, ast.FunctionDef) and n.name == 'robot_state_publisher')
    source = ast.unparse(function)
    assert "get_package_prefix('robot_state_publisher')" in source
    assert 'except PackageNotFoundError' in source
    assert "'mover6.urdf'" in source
    # The other OpaqueFunctions: the local DDS configuration (local_dds), as launch.sh sets it,
    # and the nodes of the ``hardware`` argument.
    assert sorted(ast.unparse(keyword(c, 'function')) for c in calls(tree, 'OpaqueFunction')) \
        == ['hardware_nodes', 'local_dds_environment', 'robot_state_publisher']


class Recorded:
    """A stand-in for a launch or launch_ros class: keeps its arguments (test double)."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class Configuration(Recorded):
    """LaunchConfiguration: ``perform`` reads the context's values."""

    def perform(self, context):
        return context[self.args[0]]


class Event:
    """A process output event: its ``text``."""

    def __init__(self, text):
        self.text = text


def stub_modules():
    """Return stand-ins for the modules of ``launch`` and ``launch_ros`` the launch file uses."""
    import types
    names = {
        'launch': ['LaunchDescription'],
        'launch.actions': ['DeclareLaunchArgument', 'ExecuteProcess', 'LogInfo',
                           'OpaqueFunction', 'RegisterEventHandler', 'SetEnvironmentVariable',
                           'Shutdown'],
        'launch.conditions': ['IfCondition'],
        'launch.event_handlers': ['OnProcessIO', 'OnShutdown'],
        'launch.substitutions': ['PathJoinSubstitution', 'PythonExpression'],
        'launch_ros': [], 'launch_ros.actions': ['Node'],
        'launch_ros.parameter_descriptions': ['ParameterValue'],
        'launch_ros.substitutions': ['FindPackageShare'],
    }
    modules = {}
    for module, classes in names.items():
        modules[module] = types.ModuleType(module)
        for name in classes:
            setattr(modules[module], name, type(name, (Recorded,), {}))
    modules['launch.substitutions'].LaunchConfiguration = Configuration
    return modules


@pytest.fixture(scope='module')
def launch_module():
    """Return the launch file executed on stand-ins of launch and launch_ros (not installed)."""
    import importlib.util
    import sys
    with pytest.MonkeyPatch.context() as patch:
        for name, module in stub_modules().items():
            patch.setitem(sys.modules, name, module)
        spec = importlib.util.spec_from_file_location('mover6_launch', LAUNCH_FILE)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module


def declared_arguments(launch_module):
    """Return {name: keyword arguments} of the launch file's DeclareLaunchArgument actions."""
    description = launch_module.generate_launch_description()
    return {a.args[0]: a.kwargs for a in description.args[0]
            if type(a).__name__ == 'DeclareLaunchArgument'}


def test_the_hardware_argument_starts_what_launch_sh_starts(launch_module):
    """hardware:= sim | can | can_sim: nothing more | the driver on the bus | can_sim, then it."""
    declared = declared_arguments(launch_module)
    assert [c.replace('_', '-') for c in declared['hardware']['choices']] == \
        sh_variable('HARDWARE').split()
    for name, (_, variable) in SH_NAMES.items():
        assert declared[name]['choices'] == sh_variable(variable).split()
    context = {'can_interface': 'cpr_usb2can', 'can_channel': '', 'jog_units': 'rad_per_s'}
    assert launch_module.hardware_nodes({**context, 'hardware': 'sim'}) == []
    # A real arm: the driver alone, on launch.sh's default channel, not enabled at start.
    (node,) = launch_module.hardware_nodes({**context, 'hardware': 'can',
                                            'can_interface': 'socketcan'})
    assert node.kwargs['executable'] == 'driver'
    given = node.kwargs['parameters'][1]
    assert (given['can_interface'], given['can_channel'], given['enable_on_start']) == \
        ('socketcan', '/dev/ttyUSB0', False)
    # The CAN-level Mover6 on a pty at the given link, and the driver on it once it is ready.
    actions = launch_module.hardware_nodes({**context, 'hardware': 'can_sim',
                                            'can_channel': '/tmp/x/mover6-can'})
    can_sim, handler = actions
    assert os.path.basename(can_sim.kwargs['cmd'][0]) == 'can_sim'
    assert can_sim.kwargs['cmd'][1:3] == ['--link', '/tmp/x/mover6-can']
    on_output = handler.args[0].kwargs['on_stdout']
    assert on_output(Event(b'can_sim: starting')) is None
    (node,) = on_output(Event(b'can_sim: ready on /tmp/x/mover6-can'))
    given = node.kwargs['parameters'][1]
    assert (given['can_interface'], given['can_channel'], given['enable_on_start']) == \
        ('cpr_usb2can', '/tmp/x/mover6-can', True)
    assert on_output(Event(b'ready')) is None                             # once only


def test_every_node_has_its_role(tree, launch_module):
    """
    Each node and process the launch file starts takes the keywords of its role (node_roles).

    Helpers (planner, state publishers, markers, RViz) respawn after ``RESTART_DELAY``; an
    essential node (sim_bridge, can_sim, driver, controller) ends the launch when it exits.
    """
    from mover6_control.node_roles import ESSENTIAL, HELPERS, RESTART_DELAY
    starts = calls(tree, 'Node') + calls(tree, 'ExecuteProcess')
    named = []
    for call in starts:
        name = ast.literal_eval(keyword(call, 'name') or keyword(call, 'executable'))
        spread = [k.value for k in call.keywords if k.arg is None]
        assert [ast.unparse(v) for v in spread] == [f"role('{name}')"], name
        named.append(name)
    assert set(named) == {'sim_bridge', 'controller', 'planner', 'markers', 'rviz2', 'driver',
                          'can_sim', 'state_publisher', 'robot_state_publisher'}
    for name in named:
        given = launch_module.role(name)
        if name in ESSENTIAL:
            assert set(given) == {'on_exit'} and 'essential' in given['on_exit'].kwargs['reason']
        else:
            assert name in HELPERS
            assert given == {'respawn': True, 'respawn_delay': float(RESTART_DELAY)}
