"""
Start the mover6_control stack: the one that ``mover6_control.stack`` defines.

The same nodes, parameter files, parameters and choices as scripts/launch.sh, which reads the
same definition; here robot_state_publisher with config/mover6.urdf stands in for the package's
own state_publisher where that package is installed. The arguments are the stack's options
(``ros2 launch mover6_control mover6.launch.py --show-args``) and a parameter file per node
(``<node>_params``, default config/<node>.yaml):

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
``mover6_control.node_roles``). With ``hardware:=can_sim`` the driver starts once can_sim says
it is ready (its pty link exists then). Extra ROS arguments per node come from the environment
variables MOVER6_SIM_ARGS, MOVER6_CONTROLLER_ARGS, ... as for scripts/launch.sh.
"""

import os
import shlex
import shutil
import tempfile

from ament_index_python.packages import get_package_prefix, PackageNotFoundError
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, ExecuteProcess, LogInfo, OpaqueFunction,
                            RegisterEventHandler, SetEnvironmentVariable, Shutdown)
from launch.event_handlers import OnProcessIO, OnShutdown
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare
from mover6_control import stack
from mover6_control.node_roles import is_essential, RESTART_DELAY
from mover6_control.nodes.runtime import local_dds
from mover6_control.nodes.runtime.names import check_namespace

PACKAGE = 'mover6_control'


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


def node(start, namespace):
    """Return the Node of a ``stack.Start`` of kind 'node'."""
    return Node(package=PACKAGE, executable=start.executable, name=start.name, output='screen',
                namespace=namespace, **role(start.name),
                parameters=[LaunchConfiguration(f'{start.name}_params'), start.parameters],
                ros_arguments=extra_ros_args(start.extra_args))


def state_publisher(start, namespace, context):
    """
    Return robot_state_publisher with the package's URDF, where that package is installed.

    Elsewhere (the PyPI wheels) the package's own state publisher, which publishes the same
    /robot_description, /tf and /tf_static.
    """
    try:
        get_package_prefix('robot_state_publisher')
    except PackageNotFoundError:
        return [LogInfo(msg="robot_state_publisher is not installed: the package's own "
                            'state_publisher publishes /robot_description and /tf'),
                node(start, namespace)]
    urdf = os.path.join(FindPackageShare(PACKAGE).perform(context), 'config', 'mover6.urdf')
    with open(urdf) as f:
        description = ParameterValue(f.read(), value_type=str)    # a string, not YAML
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 output='screen', namespace=namespace, **role('robot_state_publisher'),
                 parameters=[{'robot_description': description,
                              'frame_prefix': start.parameters['frame_prefix']}])]


def can_sim_then_driver(can_sim, driver, namespace):
    """
    Return can_sim on its pty link and the driver on it, started once can_sim says 'ready'.

    Without a link given, the link is in a fresh temporary folder, removed at shutdown.
    """
    actions = []
    link = can_sim.parameters['link']
    if not link:
        folder = tempfile.mkdtemp(prefix='mover6-can-')
        link = os.path.join(folder, 'mover6-can')
        actions.append(RegisterEventHandler(OnShutdown(
            on_shutdown=lambda event, context: shutil.rmtree(folder, ignore_errors=True))))
    driver = stack.Start(driver.name, driver.executable, parameters={
        **driver.parameters, 'can_channel': link}, extra_args=driver.extra_args)
    process = ExecuteProcess(
        cmd=[os.path.join(get_package_prefix(PACKAGE), 'lib', PACKAGE, 'can_sim'), '--link',
             link] + extra_ros_args(can_sim.extra_args),
        name='can_sim', output='screen', **role('can_sim'))
    started = []

    def on_output(event):
        """Start the driver once can_sim says it is ready (its link exists then)."""
        if not started and b'ready' in event.text:
            started.append(True)
            return [node(driver, namespace)]
        return None
    return actions + [process, RegisterEventHandler(OnProcessIO(target_action=process,
                                                                on_stdout=on_output))]


def start_stack(context):
    """
    Start ``stack.plan`` of the arguments' values, after setting DDS to stay on this machine.

    DDS: the package's Fast DDS profile (UDP on 127.0.0.1, no shared memory) unless the user set
    DDS variables of their own (docs/dds.md). A malformed ``namespace`` is refused at start, with
    the ROS naming rule it breaks.
    """
    choices = {option.name: LaunchConfiguration(option.name).perform(context)
               for option in stack.OPTIONS if option.in_launch}
    check_namespace(choices['namespace'])
    namespace = choices['namespace']
    actions = [SetEnvironmentVariable(name, value)
               for name, value in local_dds.default_environment(os.environ).items()]
    starts = stack.plan(choices)
    by_name = {start.name: start for start in starts}
    for start in starts:
        if start.name == 'can_sim':
            actions += can_sim_then_driver(start, by_name['driver'], namespace)
        elif start.name == 'driver' and 'can_sim' in by_name:
            continue                                  # started by can_sim_then_driver
        elif start.name == 'state_publisher':
            actions += state_publisher(start, namespace, context)
        elif start.kind == 'rviz':
            actions.append(Node(
                package='rviz2', executable='rviz2', name='rviz2', output='screen',
                **role('rviz2'), arguments=['-d', os.path.join(
                    FindPackageShare(PACKAGE).perform(context), 'rviz', 'mover6.rviz')]))
        elif start.kind == 'console':
            actions.append(Node(
                package=PACKAGE, executable='console', name='console', output='screen',
                namespace=namespace, **role('console'),
                arguments=os.environ.get('MOVER6_CONSOLE_ARGS', '').split()))
        else:
            actions.append(node(start, namespace))
    return actions


def generate_launch_description():
    """Declare the stack's options and a parameter file per node; start the stack."""
    arguments = [DeclareLaunchArgument(option.name, default_value=option.default,
                                       description=option.help,
                                       **({'choices': list(option.choices)}
                                          if option.choices else {}))
                 for option in stack.OPTIONS if option.in_launch]
    files = [DeclareLaunchArgument(f'{name}_params', default_value=config_file(f'{name}.yaml'),
                                   description=f'parameter file of {name}')
             for name in stack.PARAMETER_FILES]
    return LaunchDescription(arguments + files + [OpaqueFunction(function=start_stack)])
