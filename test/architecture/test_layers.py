"""
The layers of the package import only downwards, as docs/architecture.md draws them.

Each module belongs to one layer by its folder; every import statement in it (at module level or
inside a function) may name only its own layer or the layers its layer builds on. A module that
reaches up (the kinematics importing the controller, the core importing a node, the product
importing the test harness) fails here, just as a ROS import in the core fails
``test_core_is_ros_free.py``.
"""

import ast
import os

import pytest
from source_tree import ROOT


# Layer of a module, by the longest matching dotted prefix.
LAYER_OF = {
    'mover6_control': 'base',            # errors, resources, validation, parameters
    'mover6_control.kinematics': 'kinematics',
    'mover6_control.collision': 'collision',
    'mover6_control.motion': 'motion',
    'mover6_control.control': 'control',
    'mover6_control.planning': 'planning',
    'mover6_control.programs': 'programs',
    'mover6_control.hardware': 'hardware',
    'mover6_control.nodes': 'nodes',
    'mover6_control.tools': 'tools',
    'sim_bridge': 'sim',
    'sim_bridge.bridge_node': 'sim_node',
    'sim_bridge.bridge_physics': 'sim_node',   # the bridge node's physics thread
    'sim_bridge.bridge_controls': 'sim_node',  # the bridge node's reset, pause and step
}

# What each layer may import (besides itself and third-party packages).
MAY_IMPORT = {
    'base': set(),
    'kinematics': {'base'},
    'collision': {'base', 'kinematics'},
    'motion': {'base', 'kinematics'},
    'control': {'base', 'kinematics', 'motion', 'collision'},
    'planning': {'base', 'kinematics', 'motion', 'collision'},
    'programs': {'base', 'kinematics', 'motion', 'collision', 'planning', 'hardware'},
    'hardware': {'base'},
    'sim': {'base', 'kinematics', 'collision', 'hardware'},
    'nodes': {'base', 'kinematics', 'motion', 'control', 'planning', 'collision', 'hardware',
              'programs'},
    'sim_node': {'base', 'kinematics', 'sim', 'nodes'},
    'tools': {'base', 'kinematics', 'motion', 'control', 'planning', 'nodes', 'sim',
              'collision', 'hardware', 'programs'},
}


def layer_of(module):
    """Return the layer of a dotted module name of this project, or None for anything else."""
    best = None
    for prefix in LAYER_OF:
        if module == prefix or module.startswith(prefix + '.'):
            if best is None or len(prefix) > len(best):
                best = prefix
    return LAYER_OF[best] if best else None


def project_modules():
    """Return (dotted name, path) of every module of the two Python packages."""
    out = []
    for package in ('mover6_control', 'sim_bridge'):
        for folder, dirs, files in os.walk(os.path.join(ROOT, package)):
            dirs[:] = sorted(d for d in dirs if not d.startswith(('.', '__')))
            dotted = os.path.relpath(folder, ROOT).replace(os.sep, '.')
            for name in sorted(files):
                stem, ext = os.path.splitext(name)
                if ext == '.py':
                    module = dotted if stem == '__init__' else f'{dotted}.{stem}'
                    out.append((module, os.path.join(folder, name)))
    return out


def imports_of(module, path):
    """Return every absolute module name that an import statement in ``path`` names."""
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    package = module if path.endswith('__init__.py') else module.rpartition('.')[0]
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                parts = package.split('.')
                parent = '.'.join(parts[:len(parts) - node.level + 1])
                base = f'{parent}.{base}' if base else parent
            names.append(base)
            # ``from mover6_control import motion`` names the subpackage itself.
            names += [f'{base}.{alias.name}' for alias in node.names
                      if layer_of(f'{base}.{alias.name}') not in (None, layer_of(base))]
    return names


def test_every_folder_has_a_layer():
    """Each module lands in a known layer, and each layer holds at least one module."""
    modules = project_modules()
    seen = {layer_of(m) for m, _ in modules}
    assert None not in seen
    assert seen == set(MAY_IMPORT), f'layers without modules: {set(MAY_IMPORT) - seen}'


def upward_imports(module, path):
    """Return the imports in ``path`` (module ``module``) that name a layer above its own."""
    layer = layer_of(module)
    allowed = MAY_IMPORT[layer] | {layer}
    return [f'{name} ({layer_of(name)})' for name in imports_of(module, path)
            if layer_of(name) is not None and layer_of(name) not in allowed]


def test_the_check_reports_a_bad_import(tmp_path):
    """A synthetic control module that reaches up to the nodes is reported; its own layer not."""
    path = tmp_path / 'reaches_up.py'
    path.write_text(
        'import numpy\n'
        'from mover6_control.control.robot import Robot\n'
        'from ..kinematics import arm\n'
        'from mover6_control import nodes\n'
        'def later():\n'
        '    from ..hardware.driver import ArmDriver\n'
        '    import mover6_control.nodes.messages.conversions\n')
    bad = upward_imports('mover6_control.control.reaches_up', str(path))
    assert bad == ['mover6_control.nodes (nodes)', 'mover6_control.hardware.driver (hardware)',
                   'mover6_control.nodes.messages.conversions (nodes)'], bad


@pytest.mark.parametrize('module,path', project_modules(), ids=lambda v: str(v))
def test_imports_only_downwards(module, path):
    """Every import names the module's own layer, a layer below it, or a third party."""
    bad = upward_imports(module, path)
    assert bad == [], f'{module} ({layer_of(module)} layer) imports from above: {bad}'


def test_the_harness_is_not_product():
    """The process harness of the tests lives in test/, and nothing in the product imports it."""
    assert os.path.exists(os.path.join(ROOT, 'test', 'ros_testing.py'))
    for module, path in project_modules():
        assert not any(n.split('.')[0] == 'ros_testing' for n in imports_of(module, path)), module


def test_the_architecture_page_draws_the_rule():
    """The mermaid arrows of docs/architecture.md are exactly the MAY_IMPORT table."""
    with open(os.path.join(ROOT, 'docs', 'architecture.md')) as f:
        text = f.read()
    block = text.split('```mermaid', 1)[1].split('```', 1)[0]
    drawn = set()
    for line in block.splitlines():
        parts = line.split('-->')
        if len(parts) == 2:
            drawn.add((parts[0].strip(), parts[1].strip()))
    rule = {(layer, below) for layer, allowed in MAY_IMPORT.items() for below in allowed}
    assert drawn == rule, f'missing arrows {rule - drawn}, extra arrows {drawn - rule}'


def test_the_architecture_page_names_every_module():
    """Each module is named in the box of its layer in docs/architecture.md's diagram."""
    with open(os.path.join(ROOT, 'docs', 'architecture.md')) as f:
        block = f.read().split('```mermaid', 1)[1].split('```', 1)[0]
    boxes = {}
    for line in block.splitlines():
        name, _, label = line.strip().partition('["')
        if label:
            boxes[name] = set(label.replace('<br>', ',').replace(':', ',').replace('"]', '')
                              .replace(' ', ',').split(','))
    box_of = {'base': 'base', 'sim': 'sim', 'sim_node': 'sim_node'}
    unnamed = []
    for module, path in project_modules():
        stem = module.rpartition('.')[2]
        if path.endswith('__init__.py'):
            continue
        layer = layer_of(module)
        if stem not in boxes[box_of.get(layer, layer)]:
            unnamed.append(module)
    assert unnamed == [], f'modules the diagram does not name: {unnamed}'
