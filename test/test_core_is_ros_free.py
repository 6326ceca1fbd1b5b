"""
The core stays ROS-free: no rclpy, no message or service package, imported or pulled in.

Nodes (and the modules that exist to talk ROS: conversions, the goal client, the demo, the test
harness) are the only places allowed to. Checked twice: statically on every import statement,
and dynamically by importing each core module in a fresh interpreter and looking at what got
loaded.
"""

import ast
import os
import re
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROS_SIDE = {'mover6_control': {'planner_node', 'controller_node', 'goal_cli', 'demo_cli',
                               'conversions', 'ros_testing'},
            'sim_bridge': {'bridge_node'}}
FORBIDDEN = re.compile(r'^(rclpy|rosidl\w*|rcl_interfaces|builtin_interfaces|\w+_msgs|\w+_srvs)'
                       r'(\.|$)')


def core_modules():
    """Return the dotted names of every core module."""
    out = []
    for package, ros_side in ROS_SIDE.items():
        for name in sorted(os.listdir(os.path.join(ROOT, package))):
            stem, ext = os.path.splitext(name)
            if ext == '.py' and stem not in ros_side:
                out.append(f'{package}.{stem}' if stem != '__init__' else package)
    return out


def imported_names(path):
    """Return every module name an import statement in ``path`` names."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


def test_the_core_list_is_not_empty():
    """The check below covers the modules it should (guards against a wrong folder)."""
    modules = core_modules()
    for expected in ('mover6_control.ik', 'mover6_control.controller_core',
                     'mover6_control.planning', 'sim_bridge.simulator'):
        assert expected in modules


@pytest.mark.parametrize('module', core_modules())
def test_no_ros_import_statement(module):
    """No import statement of a core module names rclpy or a message/service package."""
    path = os.path.join(ROOT, *module.split('.'))
    path = os.path.join(path, '__init__.py') if os.path.isdir(path) else path + '.py'
    bad = [name for name in imported_names(path) if FORBIDDEN.match(name)]
    assert bad == [], f'{module} imports {bad}: the core must stay ROS-free'


def test_forbidden_pattern_catches_ros_packages():
    """The pattern is not vacuous: it matches what it must and spares what it may."""
    for name in ('rclpy', 'rclpy.node', 'std_msgs.msg', 'control_msgs', 'std_srvs.srv',
                 'rcl_interfaces.msg'):
        assert FORBIDDEN.match(name), name
    for name in ('numpy', 'scipy.spatial', 'mujoco', 'mover6_control.arm', 'ruckig'):
        assert not FORBIDDEN.match(name), name


def test_importing_the_core_loads_no_ros():
    """Importing every core module in a fresh interpreter loads neither rclpy nor messages."""
    code = ('import sys\n'
            f'for m in {core_modules()!r}:\n'
            '    __import__(m)\n'
            'print("\\n".join(sorted(sys.modules)))\n')
    env = dict(os.environ, MUJOCO_GL=os.environ.get('MUJOCO_GL', 'egl'))
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    assert 'mover6_control.ik' in out
    loaded = [m for m in out if FORBIDDEN.match(m)]
    assert loaded == [], f'importing the core loaded {loaded}'
