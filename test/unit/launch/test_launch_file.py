"""
launch/mover6.launch.py and scripts/launch.sh both start ``mover6_control.stack``'s plan.

The launch file needs the ``launch`` and ``launch_ros`` packages, which this environment may not
have (launch_ros is not on PyPI), so it is executed on stand-ins that record what it builds: its
arguments must be the stack's options and a parameter file per node, and for each choice of the
options the nodes it starts must be the plan's (executable, parameter file, parameters, extra
arguments, role). launch.sh must evaluate the stack's shell lines; their start lines are the
plan's too (test/unit/base/test_stack.py). What ``ros2 launch`` itself then does with the
actions is not tested here.
"""

import importlib.util
import os
import sys
import types

from mover6_control import stack
from mover6_control.node_roles import ESSENTIAL, HELPERS, RESTART_DELAY
from mover6_control.resources import CONFIG_DIR
import pytest

ROOT = os.path.dirname(CONFIG_DIR)
LAUNCH_FILE = os.path.join(ROOT, 'launch', 'mover6.launch.py')
LAUNCH_SH = os.path.join(ROOT, 'scripts', 'launch.sh')


def read(path):
    """Return the text of ``path``."""
    with open(path) as f:
        return f.read()


class Recorded:
    """A stand-in for a launch or launch_ros class: keeps its arguments (test double)."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class Configuration(Recorded):
    """LaunchConfiguration: ``perform`` reads the context's values."""

    def perform(self, context):
        return context[self.args[0]]


class Share(Recorded):
    """FindPackageShare: ``perform`` gives the source tree (where config/ and rviz/ are)."""

    def perform(self, context):
        return ROOT


class Event:
    """A process output event: its ``text``."""

    def __init__(self, text):
        self.text = text


def stub_modules():
    """Return stand-ins for the modules of ``launch`` and ``launch_ros`` the launch file uses."""
    names = {
        'launch': ['LaunchDescription'],
        'launch.actions': ['DeclareLaunchArgument', 'ExecuteProcess', 'LogInfo',
                           'OpaqueFunction', 'RegisterEventHandler', 'SetEnvironmentVariable',
                           'Shutdown'],
        'launch.event_handlers': ['OnProcessIO', 'OnShutdown'],
        'launch.substitutions': ['PathJoinSubstitution'],
        'launch_ros': [], 'launch_ros.actions': ['Node'],
        'launch_ros.parameter_descriptions': ['ParameterValue'],
        'launch_ros.substitutions': [],
    }
    modules = {}
    for module, classes in names.items():
        modules[module] = types.ModuleType(module)
        for name in classes:
            setattr(modules[module], name, type(name, (Recorded,), {}))
    modules['launch.substitutions'].LaunchConfiguration = Configuration
    modules['launch_ros.substitutions'].FindPackageShare = Share
    return modules


@pytest.fixture(scope='module')
def launch_module():
    """Return the launch file executed on stand-ins of launch and launch_ros (not installed)."""
    with pytest.MonkeyPatch.context() as patch:
        for name, module in stub_modules().items():
            patch.setitem(sys.modules, name, module)
        spec = importlib.util.spec_from_file_location('mover6_launch', LAUNCH_FILE)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module


def declared(launch_module):
    """Return {name: keyword arguments} of the launch file's DeclareLaunchArgument actions."""
    description = launch_module.generate_launch_description()
    return {a.args[0]: a.kwargs for a in description.args[0]
            if type(a).__name__ == 'DeclareLaunchArgument'}


def started(launch_module, choices):
    """
    Return {name: (executable, parameters, ros arguments)} of what the launch file starts.

    Nodes and processes alike; the driver of ``can_sim`` once can_sim's output says 'ready'.
    """
    context = {option.name: option.default for option in stack.OPTIONS if option.in_launch}
    context.update(choices)
    out = {}
    for action in launch_module.start_stack(context):
        kind = type(action).__name__
        if kind == 'Node':
            out[action.kwargs['name'] if 'name' in action.kwargs
                else action.kwargs['executable']] = action
        elif kind == 'ExecuteProcess':
            out['can_sim'] = action
        elif kind == 'RegisterEventHandler' and type(action.args[0]).__name__ == 'OnProcessIO':
            on_output = action.args[0].kwargs['on_stdout']
            assert on_output(Event(b'can_sim: starting')) is None
            (driver,) = on_output(Event(b'can_sim: ready'))
            assert on_output(Event(b'ready')) is None                 # once only
            out['driver'] = driver
    return out


def test_launch_file_is_installed():
    assert "glob('launch/*.launch.py')" in read(os.path.join(ROOT, 'setup.py'))


def test_the_arguments_are_the_stacks_options_and_a_file_per_node(launch_module):
    arguments = declared(launch_module)
    options = [o for o in stack.OPTIONS if o.in_launch]
    files = [f'{name}_params' for name in stack.PARAMETER_FILES]
    assert list(arguments) == [o.name for o in options] + files
    for option in options:
        given = arguments[option.name]
        assert given['default_value'] == option.default
        assert given.get('choices', []) == list(option.choices)
    for name in stack.PARAMETER_FILES:
        assert arguments[f'{name}_params']['default_value'].args[0][1:] == \
            ['config', f'{name}.yaml']
        assert os.path.isfile(os.path.join(CONFIG_DIR, f'{name}.yaml'))


CHOICES = [{}, {'sim': 'false'}, {'hardware': 'can', 'can_interface': 'socketcan'},
           {'hardware': 'can_sim', 'can_channel': '/tmp/x/mover6-can', 'rviz': 'true'},
           {'jog_units': 'fraction_of_max', 'profile': 'trapezoidal', 'namespace': 'arm2',
            'limit_set': 'hardware'}]


@pytest.mark.parametrize('choices', CHOICES, ids=lambda c: ','.join(c.values()) or 'defaults')
def test_the_launch_file_starts_the_stacks_plan(launch_module, choices, monkeypatch):
    """Every Start of the plan, with its parameter file, parameters, extra arguments and role."""
    monkeypatch.setenv('MOVER6_CONTROLLER_ARGS', '-p t_max:=2.0')
    nodes = started(launch_module, choices)
    plan = stack.plan(choices)
    assert set(nodes) == {s.name for s in plan}
    for start in plan:
        action = nodes[start.name]
        if start.kind == 'process':
            assert os.path.basename(action.kwargs['cmd'][0]) == 'can_sim'
            assert action.kwargs['cmd'][1:3] == ['--link', start.parameters['link']]
        elif start.kind == 'node':
            assert action.kwargs['executable'] == start.executable
            assert action.kwargs['namespace'] == choices.get('namespace', '')
            first, given = action.kwargs['parameters']
            assert first.args == (f'{start.name}_params',)
            assert given == start.parameters
            expected = ['-p', 't_max:=2.0'] if start.name == 'controller' else []
            assert action.kwargs['ros_arguments'] == expected
        keys = ('on_exit', 'respawn', 'respawn_delay')
        given = {k: v for k, v in action.kwargs.items() if k in keys}
        if start.name in ESSENTIAL:
            assert set(given) == {'on_exit'}, start.name
            assert 'essential' in given['on_exit'].kwargs['reason']
        else:
            assert start.name in HELPERS
            assert given == {'respawn': True, 'respawn_delay': float(RESTART_DELAY)}


def test_robot_state_publisher_stands_in_where_installed(launch_module, monkeypatch):
    """With robot_state_publisher installed it publishes the URDF, with the stack's prefix."""
    monkeypatch.setattr(launch_module, 'get_package_prefix', lambda name: '/opt/ros/jazzy')
    node = started(launch_module, {'namespace': '/arm1'})['robot_state_publisher']
    (given,) = node.kwargs['parameters']
    assert given['frame_prefix'] == 'arm1/'
    assert '<robot' in given['robot_description'].args[0]
    assert node.kwargs['respawn'] is True


def test_launch_sh_starts_the_stacks_shell_lines():
    """launch.sh evaluates the stack's values and start lines; it defines what they call."""
    script = read(LAUNCH_SH)
    assert 'setup=$(python3 -m mover6_control.tools.launch_shell -- "$@")' in script
    assert 'eval "$setup"' in script and '\nstart_stack\n' in script
    for function in ('start()', 'start_can_sim()', 'start_command()'):
        assert function in script
    assert 'exec python3 -m mover6_control.stack help' in script
