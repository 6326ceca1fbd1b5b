"""
Start the mover6_control nodes: the arm (sim_bridge, or the CAN driver), controller, planner.

The same nodes, parameter files and choices as scripts/launch.sh
(test/unit/launch/test_launch_file.py keeps the two in step), plus robot_state_publisher with
config/mover6.urdf when that package is installed, else the package's own state_publisher (as
launch.sh), the markers node, and RViz with rviz/mover6.rviz on ``rviz:=true``:

    ros2 launch mover6_control mover6.launch.py
    ros2 launch mover6_control mover6.launch.py sim:=false jog_units:=fraction_of_max
    ros2 launch mover6_control mover6.launch.py profile:=trapezoidal limit_set:=hardware
    ros2 launch mover6_control mover6.launch.py controller_params:=/path/to/controller.yaml
    ros2 launch mover6_control mover6.launch.py hardware:=can_sim
    ros2 launch mover6_control mover6.launch.py rviz:=true
    ros2 launch mover6_control mover6.launch.py namespace:=arm2
    ros2 launch mover6_control mover6.launch.py hardware:=can can_interface:=socketcan \
        can_channel:=can0

Essential nodes (the arm, the driver, the controller) end the launch when they exit; helpers
(planner, state publisher, markers, RViz) are started again (``role``, from the one table
``mover6_control.node_roles``, which scripts/launch.sh reads too).

``hardware``: ``sim`` (default) runs sim_bridge; ``can_sim`` runs the CAN-level Mover6
(``can_sim``) on a pty and, once it is up, the driver on that pty, enabled at start; ``can``
runs the driver on ``can_interface`` / ``can_channel`` (default the CPR USB2CAN adapter on
/dev/ttyUSB0), not active: activate it (docs/driver.md). With the driver the controller's
state_timeout is 0.5 s (the driver publishes /joint_states at its 20 Hz cycle). The timed threads
(the controller's tick, the bridge's physics, the driver's cycle) run at SCHED_FIFO 50 where the
system allows it (``tick_priority``, ``physics_priority``, ``cycle_priority`` in the parameter
files; without the right each node says so once and runs at normal scheduling).

``profile``, ``jog_units`` and ``limit_set`` override the parameter files; their choices and
defaults are the controller's parameter table's (``mover6_control.parameters``), whose defaults
are the shipped files' values. With ``jog_units:=fraction_of_max`` the simulator runs as the vendor
driver (mode vendor_driver). Extra ROS arguments per node, as for scripts/launch.sh, come from
the environment variables MOVER6_SIM_ARGS, MOVER6_CONTROLLER_ARGS and MOVER6_PLANNER_ARGS.
"""

import os
import shlex
import shutil
import tempfile

from ament_index_python.packages import get_package_prefix, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, ExecuteProcess, LogInfo, OpaqueFunction,
                            RegisterEventHandler, SetEnvironmentVariable, Shutdown)
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessIO, OnShutdown
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare
from mover6_control.node_roles import is_essential, RESTART_DELAY
from mover6_control.nodes.runtime import local_dds
from mover6_control.nodes.runtime.names import check_namespace
from mover6_control.parameters import CONTROLLER

PACKAGE = 'mover6_control'
# [s] the controller's state timeout: its parameter's on the simulator, 0.5 s behind the driver.
STATE_TIMEOUT = {'sim': str(CONTROLLER['state_timeout'].default), 'can_sim': '0.5', 'can': '0.5'}
# Every node in the ``namespace`` argument; TF frames prefixed with it (/arm1 -> arm1/).
NAMESPACE = LaunchConfiguration('namespace')
TF_PREFIX = PythonExpression(["(lambda n: n + '/' if n else '')('", NAMESPACE, "'.strip('/'))"])


def role(name):
    """
    Return the launch keywords of a node by its kind: essential or helper (node_roles).

    A helper is started again ``RESTART_DELAY`` after it exits (launch_ros's respawn; launch.sh
    doubles the delay each time); an essential node's exit ends the launch, every node with it.
    """
    if is_essential(name):
        return {'on_exit': Shutdown(reason=f'{name} exited: an essential node, the stack stops')}
    return {'respawn': True, 'respawn_delay': float(RESTART_DELAY)}


def config_file(name):
    """Return the path of the installed config file ``name``, as a substitution."""
    return PathJoinSubstitution([FindPackageShare(PACKAGE), 'config', name])


def extra_ros_args(variable):
    """Return the ROS arguments in environment variable ``variable`` (scripts/launch.sh's hook)."""
    return shlex.split(os.environ.get(variable, ''))


def robot_state_publisher(context):
    """
    Start robot_state_publisher with the package's URDF, where that package is installed.

    Elsewhere (the PyPI wheels) the package's own state publisher, which publishes the same
    /robot_description, /tf and /tf_static.
    """
    urdf = os.path.join(FindPackageShare(PACKAGE).perform(context), 'config', 'mover6.urdf')
    try:
        get_package_prefix('robot_state_publisher')
    except PackageNotFoundError:
        return [LogInfo(msg="robot_state_publisher is not installed: the package's own "
                            'state_publisher publishes /robot_description and /tf'),
                Node(package=PACKAGE, executable='state_publisher', name='state_publisher',
                     output='screen', namespace=NAMESPACE, **role('state_publisher'),
                     parameters=[LaunchConfiguration('state_publisher_params'),
                                 {'frame_prefix': TF_PREFIX}],
                     ros_arguments=extra_ros_args('MOVER6_STATE_PUBLISHER_ARGS'))]
    with open(urdf) as f:
        description = ParameterValue(f.read(), value_type=str)    # a string, not YAML
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 output='screen', namespace=NAMESPACE, **role('robot_state_publisher'),
                 parameters=[{'robot_description': description, 'frame_prefix': TF_PREFIX}])]


def local_dds_environment(context):
    """
    Set DDS to stay on this machine, unless the user set DDS variables of their own.

    Also refuses a malformed ``namespace`` at start, with the ROS naming rule it breaks.
    """
    check_namespace(NAMESPACE.perform(context))
    return [SetEnvironmentVariable(name, value)
            for name, value in local_dds.default_environment(os.environ).items()]


def driver(can_interface, can_channel, enable_on_start):
    """Return the driver node on ``can_interface`` / ``can_channel``."""
    return Node(
        package=PACKAGE, executable='driver', name='driver', output='screen',
        namespace=NAMESPACE, **role('driver'),
        parameters=[LaunchConfiguration('driver_params'),
                    {'can_interface': can_interface, 'can_channel': can_channel,
                     'jog_units': LaunchConfiguration('jog_units'),
                     'limit_set': LaunchConfiguration('limit_set'),
                     'enable_on_start': enable_on_start}],
        ros_arguments=extra_ros_args('MOVER6_DRIVER_ARGS'))


def hardware_nodes(context):
    """Start what the ``hardware`` argument asks for besides sim_bridge (see the docstring)."""
    hardware = LaunchConfiguration('hardware').perform(context)
    channel = LaunchConfiguration('can_channel').perform(context)
    if hardware == 'can':
        return [driver(LaunchConfiguration('can_interface').perform(context),
                       channel or '/dev/ttyUSB0', False)]
    if hardware != 'can_sim':
        return []
    actions = []
    link = channel
    if not link:
        folder = tempfile.mkdtemp(prefix='mover6-can-')
        link = os.path.join(folder, 'mover6-can')
        actions.append(RegisterEventHandler(OnShutdown(
            on_shutdown=lambda event, context: shutil.rmtree(folder, ignore_errors=True))))
    can_sim = ExecuteProcess(
        cmd=[os.path.join(get_package_prefix(PACKAGE), 'lib', PACKAGE, 'can_sim'), '--link',
             link] + shlex.split(os.environ.get('MOVER6_CAN_SIM_ARGS', '')),
        name='can_sim', output='screen', **role('can_sim'))
    started = []

    def on_output(event):
        """Start the driver once can_sim says it is ready (its link exists then)."""
        if not started and b'ready' in event.text:
            started.append(True)
            return [driver('cpr_usb2can', link, True)]
        return None
    return actions + [can_sim, RegisterEventHandler(OnProcessIO(target_action=can_sim,
                                                                on_stdout=on_output))]


def parameter_argument(name, description):
    """Return the launch argument of controller parameter ``name``: its choices, default first."""
    spec = CONTROLLER[name]
    choices = [spec.default] + [choice for choice in spec.allowed if choice != spec.default]
    return DeclareLaunchArgument(name, default_value=spec.default, choices=choices,
                                 description=description)


def generate_launch_description():
    """Declare the arguments and the nodes."""
    sim = LaunchConfiguration('sim')
    profile = LaunchConfiguration('profile')
    jog_units = LaunchConfiguration('jog_units')
    limit_set = LaunchConfiguration('limit_set')
    hardware = LaunchConfiguration('hardware')
    sim_mode = PythonExpression(
        ["'vendor_driver' if '", jog_units, "' == 'fraction_of_max' else 'rad_per_s'"])
    with_sim = PythonExpression(["'", sim, "' == 'true' and '", hardware, "' == 'sim'"])
    state_timeout = PythonExpression([repr(STATE_TIMEOUT), "['", hardware, "']"])
    cycle_driver = PythonExpression(["'", hardware, "' != 'sim'"])   # the driver's set-points
    return LaunchDescription([
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='namespace of every node, topic, service and action (a second arm: '
                        'arm2); TF frames are prefixed with it'),
        DeclareLaunchArgument(
            'sim', default_value='true', choices=['true', 'false'],
            description='true: the MuJoCo bridge stands in for the arm; false: a real driver'),
        DeclareLaunchArgument(
            'hardware', default_value='sim', choices=['sim', 'can_sim', 'can'],
            description='sim: the MuJoCo bridge; can_sim: the CAN-level Mover6 on a pty and the '
                        'driver on it; can: the driver on a real arm (can_interface, '
                        'can_channel)'),
        DeclareLaunchArgument(
            'can_interface', default_value='cpr_usb2can',
            description='bus of the driver with hardware:=can: cpr_usb2can, socketcan, pcan, ...'),
        DeclareLaunchArgument(
            'can_channel', default_value='',
            description='its channel (/dev/ttyUSB0 by default, can0, ...); with can_sim the '
                        'link of the pty (default: in a fresh temporary folder)'),
        DeclareLaunchArgument(
            'driver_params', default_value=config_file('driver.yaml'),
            description='parameter file of the driver'),
        parameter_argument('profile', 'controller velocity profile'),
        parameter_argument('jog_units', 'JointJog units: rad_per_s (ROS standard) or '
                                        'fraction_of_max (the vendor cpr driver; the simulator '
                                        'then runs as that driver)'),
        parameter_argument('limit_set', 'joint limits of every node: within_90_deg or hardware '
                                        '(vendor)'),
        DeclareLaunchArgument(
            'sim_bridge_params', default_value=config_file('sim_bridge.yaml'),
            description='parameter file of sim_bridge'),
        DeclareLaunchArgument(
            'controller_params', default_value=config_file('controller.yaml'),
            description='parameter file of the controller'),
        DeclareLaunchArgument(
            'planner_params', default_value=config_file('planner.yaml'),
            description='parameter file of the planner'),
        DeclareLaunchArgument(
            'markers_params', default_value=config_file('markers.yaml'),
            description='parameter file of the markers node (goal, planned path, table, '
                        'keep-out boxes on /markers)'),
        DeclareLaunchArgument(
            'rviz', default_value='false', choices=['true', 'false'],
            description='true: start RViz (rviz2, where installed) with rviz/mover6.rviz'),
        DeclareLaunchArgument(
            'state_publisher_params', default_value=config_file('state_publisher.yaml'),
            description='parameter file of the state publisher (without robot_state_publisher)'),
        # DDS stays on this machine (the package's Fast DDS profile: UDP on 127.0.0.1, no shared
        # memory) unless the user chose their own DDS setup (a robot network); README, "DDS".
        OpaqueFunction(function=local_dds_environment),
        Node(
            package=PACKAGE, executable='sim_bridge', name='sim_bridge', output='screen',
            namespace=NAMESPACE, **role('sim_bridge'),
            condition=IfCondition(with_sim),
            parameters=[LaunchConfiguration('sim_bridge_params'),
                        {'limit_set': limit_set, 'mode': sim_mode}],
            ros_arguments=extra_ros_args('MOVER6_SIM_ARGS')),
        Node(
            package=PACKAGE, executable='controller', name='controller', output='screen',
            namespace=NAMESPACE, **role('controller'),
            parameters=[LaunchConfiguration('controller_params'),
                        {'profile': profile, 'jog_units': jog_units, 'limit_set': limit_set,
                         'state_timeout': ParameterValue(state_timeout, value_type=float),
                         'cycle_driver': ParameterValue(cycle_driver, value_type=bool)}],
            ros_arguments=extra_ros_args('MOVER6_CONTROLLER_ARGS')),
        Node(
            package=PACKAGE, executable='planner', name='planner', output='screen',
            namespace=NAMESPACE, **role('planner'),
            parameters=[LaunchConfiguration('planner_params'),
                        {'profile': profile, 'limit_set': limit_set}],
            ros_arguments=extra_ros_args('MOVER6_PLANNER_ARGS')),
        Node(
            package=PACKAGE, executable='markers', name='markers', output='screen',
            namespace=NAMESPACE, **role('markers'),
            parameters=[LaunchConfiguration('markers_params'), {'frame_prefix': TF_PREFIX}],
            ros_arguments=extra_ros_args('MOVER6_MARKERS_ARGS')),
        Node(
            package='rviz2', executable='rviz2', name='rviz2', output='screen', **role('rviz2'),
            condition=IfCondition(LaunchConfiguration('rviz')),
            arguments=['-d', PathJoinSubstitution([FindPackageShare(PACKAGE), 'rviz',
                                                   'mover6.rviz'])]),
        OpaqueFunction(function=hardware_nodes),
        OpaqueFunction(function=robot_state_publisher),
    ])
