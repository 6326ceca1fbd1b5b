"""
Where the package's data files (URDF, meshes, DH tables, parameter YAML) are; its executables.

In a source checkout that is ``<repo>/config``; in an installed package (colcon install, a ROS 2
workspace) it is ``share/mover6_control/config``, found through the ament index.

``EXECUTABLES`` is the one table of the package's executables (``ros2 run mover6_control
NAME``) and the module whose ``main()`` each runs: setup.py makes its entry points from it, and
``executable_command`` starts one (the installed executable, or ``python -m`` from a source
tree). No import here beyond the standard library: setup.py reads this file before the package
is built.
"""

import os
import sys

EXECUTABLES = {
    'planner': 'mover6_control.nodes.planner.node',
    'controller': 'mover6_control.nodes.controller.node',
    'sim_bridge': 'sim_bridge.bridge_node',
    'driver': 'mover6_control.nodes.driver.node',
    'can_sim': 'sim_bridge.can_sim',
    'goal': 'mover6_control.tools.goal_cli',
    'teleop': 'mover6_control.tools.teleop',
    'state_publisher': 'mover6_control.nodes.state_publisher.node',
    'markers': 'mover6_control.nodes.markers.node',
    'recorder': 'mover6_control.nodes.recorder.node',
    'first_run': 'mover6_control.tools.first_run',
    'console': 'mover6_control.nodes.console.node',
    'program': 'mover6_control.tools.program_cli',
}

_SOURCE_CONFIG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                              'config')


def _find_config_dir():
    if os.path.isdir(_SOURCE_CONFIG):
        return _SOURCE_CONFIG
    try:
        from ament_index_python.packages import get_package_share_directory
        return os.path.join(get_package_share_directory('mover6_control'), 'config')
    except (ImportError, LookupError):
        return _SOURCE_CONFIG


CONFIG_DIR = _find_config_dir()
# The package's share folder (the repository in a source checkout): config/, meshes/ ...
SHARE_DIR = os.path.dirname(CONFIG_DIR)
# The maker's meshes of the arm's links (Joint0.stl = base_link .. Joint6.stl = link6).
MESH_DIR = os.path.join(SHARE_DIR, 'meshes')
PACKAGE_URL = 'package://mover6_control/'


def package_file(url: str) -> str:
    """Return the file of a ``package://mover6_control/...`` URL (a plain path as it is)."""
    if url.startswith(PACKAGE_URL):
        return os.path.join(SHARE_DIR, url[len(PACKAGE_URL):])
    return url


def executable_command(name: str) -> list[str]:
    """Return the command that runs executable ``name``: installed, or ``python -m`` its module."""
    try:
        from ament_index_python.packages import get_package_prefix
        exe = os.path.join(get_package_prefix('mover6_control'), 'lib', 'mover6_control', name)
        if os.access(exe, os.X_OK):
            return [exe]
    except Exception:  # noqa: B902 - not built: run from the source tree
        pass
    return [sys.executable, '-m', EXECUTABLES[name]]
