"""
Where the package's data files (URDF, DH tables, parameter YAML) are.

In a source checkout that is ``<repo>/config``; in an installed package (colcon install, a ROS 2
workspace) it is ``share/mover6_control/config``, found through the ament index.
"""

import os

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
