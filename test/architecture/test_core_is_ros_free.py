"""
The core stays ROS-free: no rclpy, no message or service package, imported or pulled in.

ROS lives in ``mover6_control/nodes/`` (the nodes and the one message-conversion module), in
``mover6_control/tools/`` (the goal command line and the demo talk to the nodes) and in
``sim_bridge/bridge_node.py`` (with its physics thread, ``bridge_physics.py``); everything else
is the core (the bridge node's ROS-free controls, ``bridge_controls.py``, included). Checked
twice: statically on every import statement, and dynamically by importing each core module in a
fresh interpreter and looking at what got loaded.
"""

import ast
import os
import re
import subprocess
import sys

import pytest
from source_tree import ROOT

PACKAGES = ('mover6_control', 'sim_bridge')
ROS_SIDE = ('mover6_control.nodes', 'mover6_control.tools', 'sim_bridge.bridge_node',
            'sim_bridge.bridge_physics')
FORBIDDEN = re.compile(r'^(rclpy|rosidl\w*|rcl_interfaces|builtin_interfaces|\w+_msgs|\w+_srvs)'
                       r'(\.|$)')


def core_modules():
    """Return the dotted names of every core module."""
    out = []
    for package in PACKAGES:
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = sorted(d for d in dirs if not d.startswith(('.', '__')))
            dotted = os.path.relpath(folder, ROOT).replace(os.sep, '.')
            for name in sorted(files):
                stem, ext = os.path.splitext(name)
                if ext != '.py':
                    continue
                module = dotted if stem == '__init__' else f'{dotted}.{stem}'
                if not any(module == r or module.startswith(r + '.') for r in ROS_SIDE):
                    out.append(module)
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
    for expected in ('mover6_control.kinematics.ik_closed_form',
                     'mover6_control.control.controller_core',
                     'mover6_control.planning.planner_core', 'sim_bridge.simulator'):
        assert expected in modules
    for ros_side in ('mover6_control.nodes.controller.node', 'mover6_control.tools.goal_cli',
                     'sim_bridge.bridge_node'):
        assert ros_side not in modules


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
    for name in ('numpy', 'scipy.spatial', 'mujoco', 'mover6_control.kinematics.arm', 'ruckig'):
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
    assert 'mover6_control.kinematics.ik_closed_form' in out
    loaded = [m for m in out if FORBIDDEN.match(m)]
    assert loaded == [], f'importing the core loaded {loaded}'
