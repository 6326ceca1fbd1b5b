"""
Start the mover6_control nodes: sim_bridge (or none, for the real driver), controller, planner.

The same nodes, parameter files and choices as scripts/launch.sh (test/test_launch_file.py keeps
the two in step), plus robot_state_publisher with config/mover6.urdf when that package is
installed:

    ros2 launch mover6_control mover6.launch.py
    ros2 launch mover6_control mover6.launch.py sim:=false jog_units:=fraction_of_max
    ros2 launch mover6_control mover6.launch.py profile:=trapezoidal limit_set:=hardware
    ros2 launch mover6_control mover6.launch.py controller_params:=/path/to/controller.yaml

``profile``, ``jog_units`` and ``limit_set`` override the parameter files (their defaults are the
shipped files' values). With ``jog_units:=fraction_of_max`` the simulator runs as the vendor
driver (mode vendor_driver). Extra ROS arguments per node, as for scripts/launch.sh, come from
the environment variables MOVER6_SIM_ARGS, MOVER6_CONTROLLER_ARGS and MOVER6_PLANNER_ARGS.
"""

import os
import shlex

from ament_index_python.packages import get_package_prefix, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, LogInfo, OpaqueFunction, SetEnvironmentVariable
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare
from mover6_control.nodes import local_dds

PACKAGE = 'mover6_control'


def config_file(name):
    """Return the path of the installed config file ``name``, as a substitution."""
    return PathJoinSubstitution([FindPackageShare(PACKAGE), 'config', name])


def extra_ros_args(variable):
    """Return the ROS arguments in environment variable ``variable`` (scripts/launch.sh's hook)."""
    return shlex.split(os.environ.get(variable, ''))


def robot_state_publisher(context):
    """Start robot_state_publisher with the package's URDF, when that package is installed."""
    try:
        get_package_prefix('robot_state_publisher')
    except PackageNotFoundError:
        return [LogInfo(msg='robot_state_publisher is not installed: not started')]
    urdf = os.path.join(FindPackageShare(PACKAGE).perform(context), 'config', 'mover6.urdf')
    with open(urdf) as f:
        description = ParameterValue(f.read(), value_type=str)    # a string, not YAML
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 output='screen', parameters=[{'robot_description': description}])]


def local_dds_environment(context):
    """Set DDS to stay on this machine, unless the user set DDS variables of their own."""
    return [SetEnvironmentVariable(name, value)
            for name, value in local_dds.default_environment(os.environ).items()]


def generate_launch_description():
    """Declare the arguments and the nodes."""
    sim = LaunchConfiguration('sim')
    profile = LaunchConfiguration('profile')
    jog_units = LaunchConfiguration('jog_units')
    limit_set = LaunchConfiguration('limit_set')
    sim_mode = PythonExpression(
        ["'vendor_driver' if '", jog_units, "' == 'fraction_of_max' else 'rad_per_s'"])
    return LaunchDescription([
        DeclareLaunchArgument(
            'sim', default_value='true', choices=['true', 'false'],
            description='true: the MuJoCo bridge stands in for the arm; false: a real driver'),
        DeclareLaunchArgument(
            'profile', default_value='continuous',
            choices=['continuous', 'synchronised', 'trapezoidal', 'jerk_limited', 'cubic',
                     'quintic', 'septic', 'sharp_trapezoid', 'cubic_spline', 'quintic_spline',
                     'bspline', 'multi_trapezoid'],
            description='controller velocity profile'),
        DeclareLaunchArgument(
            'jog_units', default_value='rad_per_s', choices=['rad_per_s', 'fraction_of_max'],
            description='JointJog units: rad_per_s (ROS standard) or fraction_of_max (the '
                        'vendor cpr driver; the simulator then runs as that driver)'),
        DeclareLaunchArgument(
            'limit_set', default_value='within_90_deg', choices=['within_90_deg', 'hardware'],
            description='joint limits of every node: within_90_deg or hardware (vendor)'),
        DeclareLaunchArgument(
            'sim_bridge_params', default_value=config_file('sim_bridge.yaml'),
            description='parameter file of sim_bridge'),
        DeclareLaunchArgument(
            'controller_params', default_value=config_file('controller.yaml'),
            description='parameter file of the controller'),
        DeclareLaunchArgument(
            'planner_params', default_value=config_file('planner.yaml'),
            description='parameter file of the planner'),
        # DDS stays on this machine (the package's Fast DDS profile: UDP on 127.0.0.1, no shared
        # memory) unless the user chose their own DDS setup (a robot network); README, "DDS".
        OpaqueFunction(function=local_dds_environment),
        Node(
            package=PACKAGE, executable='sim_bridge', name='sim_bridge', output='screen',
            condition=IfCondition(sim),
            parameters=[LaunchConfiguration('sim_bridge_params'),
                        {'limit_set': limit_set, 'mode': sim_mode}],
            ros_arguments=extra_ros_args('MOVER6_SIM_ARGS')),
        Node(
            package=PACKAGE, executable='controller', name='controller', output='screen',
            parameters=[LaunchConfiguration('controller_params'),
                        {'profile': profile, 'jog_units': jog_units, 'limit_set': limit_set}],
            ros_arguments=extra_ros_args('MOVER6_CONTROLLER_ARGS')),
        Node(
            package=PACKAGE, executable='planner', name='planner', output='screen',
            parameters=[LaunchConfiguration('planner_params'),
                        {'profile': profile, 'limit_set': limit_set}],
            ros_arguments=extra_ros_args('MOVER6_PLANNER_ARGS')),
        OpaqueFunction(function=robot_state_publisher),
    ])
