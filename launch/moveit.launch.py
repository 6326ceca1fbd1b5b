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
``joint_states`` in its namespace, as the stack publishes them. Its planning scene monitor
publishes the monitored scene (``PLANNING_SCENE_MONITOR``), which RViz's MotionPlanning panel
shows.

Only ``launch``, ``launch_ros``, ``ament_index_python`` and PyYAML are imported: the files of
``config/moveit/`` are read as committed (``./run.sh generate`` writes the generated ones), so
the ``ros2 launch`` process needs none of the package's own libraries. Where MoveIt (the package
``moveit_ros_move_group``) is not installed, this launch starts nothing and says so, before it
reads any file.
"""

import os

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
import yaml

MOVE_GROUP_PACKAGE = 'moveit_ros_move_group'
# config/moveit/ beside this file's folder: the source tree's, or share/mover6_control/'s.
MOVEIT_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                          'config', 'moveit')
PIPELINES = {'ompl': 'ompl_planning.yaml',
             'pilz_industrial_motion_planner': 'pilz_industrial_motion_planner_planning.yaml'}
DEFAULT_PIPELINE = 'ompl'
# move_group's planning scene monitor publishes the scene and its updates (geometry, state,
# transforms) on monitored_planning_scene, as moveit_configs_utils' planning_scene_monitor()
# sets them by default.
PLANNING_SCENE_MONITOR = {
    'publish_planning_scene': True,
    'publish_geometry_updates': True,
    'publish_state_updates': True,
    'publish_transforms_updates': True,
}


def moveit_installed() -> bool:
    """Return True when ``move_group`` can be started."""
    try:
        get_package_share_directory(MOVE_GROUP_PACKAGE)
        return True
    except PackageNotFoundError:
        return False


def move_group_parameters(folder: str = MOVEIT_DIR) -> dict:
    """
    Return the parameters ``move_group`` starts with, from the files in ``folder``.

    The robot description (the collision URDF), the SRDF, kinematics, the joint and Cartesian
    limits, both pipelines (OMPL the default), the controllers and the planning scene monitor's
    flags.
    """
    def text(name):
        with open(os.path.join(folder, name)) as f:
            return f.read()

    def load(name):
        return yaml.safe_load(text(name))

    planning = load('joint_limits.yaml')
    planning.update(load('pilz_cartesian_limits.yaml'))
    parameters = {
        'robot_description': text('mover6_collision.urdf'),
        'robot_description_semantic': text('mover6.srdf'),
        'robot_description_kinematics': load('kinematics.yaml'),
        'robot_description_planning': planning,
        'planning_pipelines': list(PIPELINES),
        'default_planning_pipeline': DEFAULT_PIPELINE,
        'publish_robot_description_semantic': True,
    }
    for pipeline, name in PIPELINES.items():
        parameters[pipeline] = load(name)
    parameters.update(load('moveit_controllers.yaml'))
    parameters.update(PLANNING_SCENE_MONITOR)
    return parameters


def start(context, *args, **kwargs):
    """Return ``move_group`` with the configuration, or a message when MoveIt is missing."""
    if not moveit_installed():
        return [LogInfo(msg=f'MoveIt is not installed (no package {MOVE_GROUP_PACKAGE}): '
                            'move_group not started. Install ros-jazzy-moveit, then launch '
                            'again. The configuration is in config/moveit/ (docs/moveit.md).')]
    namespace = LaunchConfiguration('namespace').perform(context)
    use_sim_time = LaunchConfiguration('use_sim_time').perform(context) == 'true'
    parameters = move_group_parameters()
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
