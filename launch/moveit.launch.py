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

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from mover6_control.tools.moveit_config import move_group_parameters, MOVEIT_DIR

MOVE_GROUP_PACKAGE = 'moveit_ros_move_group'


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
    parameters = move_group_parameters(MOVEIT_DIR)
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
