"""
Typed edges: every public function of the ROS side (nodes/, tools/, sim_bridge/) has type hints.

A public function is a module-level function or a method of a public class whose name does not
start with ``_`` (dunders, ``__init__`` included, are left out); it needs an annotation on every
parameter but ``self``/``cls`` (``*args``, ``**kwargs`` too) and on its return. Closures inside
functions are not public.
"""

import ast
import os

import pytest
from source_tree import ROOT

pytestmark = pytest.mark.lint

FOLDERS = ('mover6_control/nodes', 'mover6_control/tools', 'sim_bridge')
# Files typed on the branch that owns them, left out until it merges (none now).
NOT_YET = set()


def public_functions(source, name='<source>'):
    """Return ``(qualified name, FunctionDef, is a method)`` of the public functions."""
    found = []

    def visit(body, prefix, in_class):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if not node.name.startswith('_'):
                    found.append((prefix + node.name, node, in_class))
            elif isinstance(node, ast.ClassDef) and not node.name.startswith('_'):
                visit(node.body, f'{prefix}{node.name}.', True)

    visit(ast.parse(source, name).body, '', False)
    return found


def missing_hints(node, is_method):
    """Return the names of the parameters without a hint (and 'return' without one)."""
    args = node.args
    params = args.posonlyargs + args.args + args.kwonlyargs
    static = any(isinstance(d, ast.Name) and d.id == 'staticmethod'
                 for d in node.decorator_list)
    if is_method and not static and params and params[0].arg in ('self', 'cls'):
        params = params[1:]
    missing = [p.arg for p in params if p.annotation is None]
    missing += [f'*{v.arg}' for v in (args.vararg, args.kwarg)
                if v is not None and v.annotation is None]
    return missing + (['return'] if node.returns is None else [])


def edge_files():
    """Return the Python files of the typed folders (relative to the package root)."""
    files = []
    for folder in FOLDERS:
        for path, dirs, names in os.walk(os.path.join(ROOT, folder)):
            dirs[:] = sorted(d for d in dirs if d != '__pycache__')
            relative = os.path.relpath(path, ROOT)
            files += [f'{relative}/{name}' for name in sorted(names) if name.endswith('.py')]
    return files


def test_the_folders_hold_the_nodes():
    """The check reads what it should (guards against a wrong folder)."""
    files = edge_files()
    for expected in ('mover6_control/nodes/controller/node.py',
                     'mover6_control/nodes/planner/node.py',
                     'mover6_control/tools/goal_cli.py', 'sim_bridge/bridge_node.py'):
        assert expected in files


@pytest.mark.parametrize('path', [f for f in edge_files() if f not in NOT_YET])
def test_every_public_function_has_type_hints(path):
    with open(os.path.join(ROOT, path)) as f:
        source = f.read()
    untyped = {name: missing for name, node, method in public_functions(source, path)
               if (missing := missing_hints(node, method))}
    assert untyped == {}, f'{path}: public functions without type hints: {untyped}'


def test_the_check_can_fail():
    """An untyped function, parameter or return is found; self, closures and dunders are not."""
    source = """
def typed(a: int, *rest: str, **more: float) -> None:
    def closure(x):
        pass


def untyped(a, b: int = 0):
    pass


class Node:
    def __init__(self, x):
        pass

    def method(self, y: int):
        pass

    @staticmethod
    def static(z) -> None:
        pass


class _Private:
    def hidden(self, w):
        pass
"""
    found = {name: missing_hints(node, method)
             for name, node, method in public_functions(source)}
    assert found == {'typed': [], 'untyped': ['a', 'return'], 'Node.method': ['return'],
                     'Node.static': ['z']}
