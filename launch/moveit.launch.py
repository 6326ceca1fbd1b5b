"""
Start MoveIt's ``move_group`` on the Mover6 with ``config/moveit/``, next to the package's stack.

    ros2 launch mover6_control mover6.launch.py                  # the arm, controller, planner
    ros2 launch mover6_control moveit.launch.py                  # then move_group
    ros2 launch mover6_control moveit.launch.py namespace:=arm2  # the stack's namespace

``move_group`` plans for the group ``mover6_arm`` (OMPL by default, Pilz's PTP / LIN / CIRC as the
pipeline ``pilz_industrial_motion_planner``) and executes through the controller's
``FollowJointTrajectory`` server, ``<namespace>/controller/follow_joint_trajectory``
(``moveit_controllers.yaml``). Its robot description is ``config/moveit/mover6_collision.urdf``:
the shipped URDF with the collision checker's shapes as collision model. It reads
``joint_states`` in its namespace, as the stack publishes them.

Where MoveIt (the package ``moveit_ros_move_group``) is not installed, this launch starts nothing
and says so: the configuration was written and checked statically on a machine without MoveIt
(docs/moveit.md says what was and was not run).
"""

import os

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
import yaml

PACKAGE = 'mover6_control'
MOVE_GROUP_PACKAGE = 'moveit_ros_move_group'
PIPELINES = {'ompl': 'ompl_planning.yaml',
             'pilz_industrial_motion_planner': 'pilz_industrial_motion_planner_planning.yaml'}
DEFAULT_PIPELINE = 'ompl'


def moveit_dir() -> str:
    """Return the folder of the MoveIt configuration (installed share, else the source tree)."""
    try:
        return os.path.join(get_package_share_directory(PACKAGE), 'config', 'moveit')
    except PackageNotFoundError:
        return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                            'config', 'moveit')


def read(folder: str, name: str) -> str:
    """Return the text of ``name`` in ``folder``."""
    with open(os.path.join(folder, name)) as f:
        return f.read()


def move_group_parameters(folder: str) -> dict:
    """Return the parameters of ``move_group`` from the files in ``folder``."""
    def load(name):
        return yaml.safe_load(read(folder, name))

    planning = load('joint_limits.yaml')
    planning.update(load('pilz_cartesian_limits.yaml'))
    parameters = {
        'robot_description': read(folder, 'mover6_collision.urdf'),
        'robot_description_semantic': read(folder, 'mover6.srdf'),
        'robot_description_kinematics': load('kinematics.yaml'),
        'robot_description_planning': planning,
        'planning_pipelines': list(PIPELINES),
        'default_planning_pipeline': DEFAULT_PIPELINE,
        'publish_robot_description_semantic': True,
    }
    for pipeline, name in PIPELINES.items():
        parameters[pipeline] = load(name)
    parameters.update(load('moveit_controllers.yaml'))
    return parameters


def moveit_installed() -> bool:
    """Return True when ``move_group`` can be started."""
    try:
        get_package_share_directory(MOVE_GROUP_PACKAGE)
        return True
    except PackageNotFoundError:
        return False


def start(context, *args, **kwargs):
    """Return ``move_group`` with the configuration, or a message when MoveIt is missing."""
    if not moveit_installed():
        return [LogInfo(msg=f'MoveIt is not installed (no package {MOVE_GROUP_PACKAGE}): '
                            'move_group not started. Install ros-jazzy-moveit, then launch '
                            'again. The configuration is in config/moveit/ (docs/moveit.md).')]
    namespace = LaunchConfiguration('namespace').perform(context)
    use_sim_time = LaunchConfiguration('use_sim_time').perform(context) == 'true'
    parameters = move_group_parameters(moveit_dir())
    parameters['use_sim_time'] = use_sim_time
    return [Node(package=MOVE_GROUP_PACKAGE, executable='move_group', namespace=namespace,
                 output='screen', parameters=[parameters])]


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments; start move_group where MoveIt is installed."""
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='',
                              description="the stack's namespace (mover6.launch.py namespace:=)"),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='true when the stack runs on /clock'),
        OpaqueFunction(function=start),
    ])
