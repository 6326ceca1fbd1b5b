"""
Every callback of every node goes through the one guard (``nodes/runtime/callback_guard.py``).

Read from the source: in the node modules (``mover6_control/nodes/`` and the bridge's node) no
subscription, service, timer or parameter callback is created but through a ``CallbackGuard``;
a future's done callback is a ``guard.wrap(...)``; an action server gets its goal and cancel
callbacks from ``guard.action_callbacks``. (A done callback that only returns a constant cannot
raise and needs none.) The tools (goal CLI, teleop, demo) are clients a user
runs, not nodes of the stack, and are left out. That the guard does what it says is tested on
real rclpy in test/node/test_callback_guard.py.
"""

import ast
import os

import pytest
from source_tree import ROOT

pytestmark = pytest.mark.lint

GUARD = 'mover6_control/nodes/runtime/callback_guard.py'
# The calls that register a callback with rclpy: only the guard makes them.
REGISTERING = ('create_subscription', 'create_service', 'create_timer',
               'add_on_set_parameters_callback', 'add_post_set_parameters_callback',
               'add_pre_set_parameters_callback', 'create_guard_condition')


def node_modules():
    """Return the paths (relative, with '/') of the node modules the rule covers."""
    folder = os.path.join(ROOT, 'mover6_control', 'nodes')
    paths = sorted(os.path.relpath(os.path.join(here, n), ROOT).replace(os.sep, '/')
                   for here, _, names in os.walk(folder) for n in names if n.endswith('.py'))
    bridge = ('bridge_node.py', 'bridge_physics.py', 'bridge_controls.py')
    return paths + [f'sim_bridge/{n}' for n in bridge]


def unguarded(source, name='<source>'):
    """Return ``[(line, what)]`` of the callbacks ``source`` registers past the guard."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        attr = func.attr if isinstance(func, ast.Attribute) else getattr(func, 'id', '')
        if attr in REGISTERING:
            found.append((node.lineno, attr))
        elif attr == 'add_done_callback':
            arg = node.args[0] if node.args else None
            constant = isinstance(arg, ast.Lambda) and isinstance(arg.body, ast.Constant)
            if not constant and not (isinstance(arg, ast.Call)
                                     and isinstance(arg.func, ast.Attribute)
                                     and arg.func.attr == 'wrap'):
                found.append((node.lineno, attr))
        elif attr == 'ActionServer':
            spread = [k.value for k in node.keywords if k.arg is None]
            if not any(isinstance(v, ast.Call) and isinstance(v.func, ast.Attribute)
                       and v.func.attr == 'action_callbacks' for v in spread):
                found.append((node.lineno, attr))
    return found


def test_the_rule_covers_the_nodes():
    paths = node_modules()
    assert GUARD in paths and 'mover6_control/nodes/markers/node.py' in paths
    assert 'sim_bridge/bridge_node.py' in paths


def test_the_check_can_fail():
    source = """
self.create_subscription(T, 'a', self.cb, 10)
self.guard.subscription(T, 'a', self.cb, 10)
future.add_done_callback(self.cb)
future.add_done_callback(self.guard.wrap('x', self.cb))
future.add_done_callback(lambda _: None)
ActionServer(node, A, 'a', self.execute, goal_callback=self.goal)
ActionServer(node, A, 'a', self.execute, **guard.action_callbacks(g, c))
node.add_post_set_parameters_callback(self.on_set)
"""
    assert [what for _, what in unguarded(source)] == [
        'create_subscription', 'add_done_callback', 'ActionServer',
        'add_post_set_parameters_callback']


@pytest.mark.parametrize('path', [p for p in node_modules() if p != GUARD])
def test_every_callback_goes_through_the_guard(path):
    with open(os.path.join(ROOT, path)) as f:
        source = f.read()
    assert unguarded(source, path) == [], f'{path}: register callbacks through its CallbackGuard'
