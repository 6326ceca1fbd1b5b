"""
One home for every concept: no two classes share a name, and shared tables live in one module.

Two classes called the same (the planner's plan and the controller's plan were both ``Plan``)
make every reader ask which one is meant; two copies of a table (``REASONS``) drift apart.
"""

import ast
import os

from mover6_control.errors import REASONS
from source_tree import ROOT


def definitions():
    """Return (name, kind, module path) of every top-level class and assignment of the product."""
    out = []
    for package in ('mover6_control', 'sim_bridge'):
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = sorted(d for d in dirs if not d.startswith(('.', '__')))
            for name in sorted(f for f in files if f.endswith('.py')):
                path = os.path.join(folder, name)
                with open(path) as f:
                    tree = ast.parse(f.read(), path)
                rel = os.path.relpath(path, ROOT)
                for node in tree.body:
                    if isinstance(node, ast.ClassDef):
                        out.append((node.name, 'class', rel))
                    elif isinstance(node, ast.Assign):
                        out += [(t.id, 'name', rel) for t in node.targets
                                if isinstance(t, ast.Name)]
                    elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        out.append((node.name, 'function', rel))
    return out


def test_no_two_classes_share_a_name():
    seen = {}
    for name, kind, path in definitions():
        if kind == 'class':
            seen.setdefault(name, []).append(path)
    assert {n: p for n, p in seen.items() if len(p) > 1} == {}


def test_shared_concepts_are_defined_once():
    homes = {'REASONS': ['mover6_control/errors.py'],
             'as_finite_array': ['mover6_control/validation.py'],
             'as_positive': ['mover6_control/validation.py'],
             'trapezoid_times': ['mover6_control/motion/timing/time_laws.py'],
             'ruckig_trajectory': ['mover6_control/motion/timing/jerk_limited.py']}
    found = {name: [] for name in homes}
    for name, _, path in definitions():
        if name in found:
            found[name].append(path.replace(os.sep, '/'))
    assert found == homes


def test_every_reason_code_is_in_the_one_table():
    """Each literal reason given to UnreachableError, a Verdict or a refusal has a meaning."""
    codes = set()
    for package in ('mover6_control', 'sim_bridge'):
        for folder, _, files in os.walk(os.path.join(ROOT, package)):
            for name in (f for f in files if f.endswith('.py')):
                path = os.path.join(folder, name)
                with open(path) as f:
                    tree = ast.parse(f.read(), path)
                for node in ast.walk(tree):
                    if not isinstance(node, ast.Call):
                        continue
                    args = [k.value for k in node.keywords if k.arg == 'reason']
                    func = node.func.attr if isinstance(node.func, ast.Attribute) else \
                        getattr(node.func, 'id', '')
                    if func == 'refuse' and len(node.args) >= 3:
                        args.append(node.args[2])
                    codes |= {a.value for a in args
                              if isinstance(a, ast.Constant) and isinstance(a.value, str)}
    assert {'out_of_reach', 'joint_limits', 'invalid_goal'} <= codes      # the scan finds them
    assert codes - set(REASONS) == set()


def test_no_constant_table_is_defined_twice():
    """A top-level UPPER_CASE name is defined in one product module; others import it."""
    homes = {}
    for name, kind, path in definitions():
        if kind == 'name' and name.isupper():
            homes.setdefault(name, set()).add(path.replace(os.sep, '/'))
    twice = {name: sorted(paths) for name, paths in homes.items() if len(paths) > 1}
    assert twice == {}
