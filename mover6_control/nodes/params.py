"""
Node parameters from ``mover6_control.parameters``: descriptors, declaration, the set check.

The one place where a ``ParameterSpec`` becomes a ROS ``ParameterDescriptor`` (description with
the unit, ``floating_point_range`` / ``integer_range``, allowed values as
``additional_constraints``, ``read_only``), used by the planner, the controller and the sim
bridge alike; and the controller's configs from its parameters (``config_from_parameters``).
"""

from typing import Callable, Optional

from mover6_control.collision.checker import CollisionSettings
from mover6_control.collision.geometry import ToolVolume
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.profiles import LawConfig
from mover6_control.control.servo import ServoConfig
from mover6_control.errors import InvalidInputError, Mover6Error
from mover6_control.kinematics.arm import LIMIT_SETS
from mover6_control.parameters import check_value, ParameterSpec
from mover6_control.planning.planner_core import PlannerSettings
from mover6_control.validation import short_text
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import ParameterException
from rclpy.node import Node

ROS_TYPES = {
    'bool': ParameterType.PARAMETER_BOOL,
    'int': ParameterType.PARAMETER_INTEGER,
    'float': ParameterType.PARAMETER_DOUBLE,
    'str': ParameterType.PARAMETER_STRING,
    'float_list': ParameterType.PARAMETER_DOUBLE_ARRAY,
}
# Longest refusal reason [characters] a set-parameters answer carries.


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """Return the ``ParameterDescriptor`` of a ``ParameterSpec``."""
    text = spec.description + (f' [{spec.unit}]' if spec.unit else '')
    d = ParameterDescriptor(name=spec.name, type=ROS_TYPES[spec.type], description=text,
                            additional_constraints=spec.constraints(),
                            read_only=spec.read_only)
    if spec.has_range and spec.type == 'float':
        d.floating_point_range = [FloatingPointRange(
            from_value=float(spec.minimum), to_value=float(spec.maximum), step=0.0)]
    elif spec.has_range and spec.type == 'int':
        d.integer_range = [IntegerRange(
            from_value=int(spec.minimum), to_value=int(spec.maximum), step=0)]
    return d


def ros_value(value: object) -> object:
    """Return a default as rclpy takes it (a tuple becomes a list)."""
    return list(value) if isinstance(value, tuple) else value


def declare(node: Node, table: dict, check_config: Optional[Callable] = None) -> Callable:
    """
    Declare every parameter of ``table`` on ``node`` and refuse invalid values from then on.

    ``check_config(get)``, when given, builds the node's whole configuration from a getter
    ``get(name)`` and raises when it is invalid (the relations between parameters: a capsule
    tool at least as long as wide, a stop threshold above its slow-down threshold ...); a set is
    checked with it on the values it would leave in force, before it is accepted, so a node's
    after-set callback applies only what this check built successfully. The set-parameters
    check is in place before the declarations, and the start values are checked as a whole once
    all are declared, so a bad start value (from a parameter file or ``-p``) stops the node
    too. Raises ``InvalidInputError`` (a ValueError) saying why.
    """
    callback = make_set_callback(table, node, check_config)
    node.add_on_set_parameters_callback(callback)
    for spec in table.values():
        try:
            node.declare_parameter(spec.name, ros_value(spec.default), descriptor(spec))
        except ParameterException as err:
            raise InvalidInputError(f'parameter {spec.name}: {err}') from err
    if check_config is not None:
        reason = whole_config_problem(check_config, lambda n: node.get_parameter(n).value)
        if reason is not None:
            raise InvalidInputError(f'parameters: {reason}')
    return callback


def whole_config_problem(check_config: Callable, get: Callable[[str], object]) -> Optional[str]:
    """Return why ``check_config(get)`` refuses the values of ``get`` (None: it takes them)."""
    try:
        check_config(get)
    except (Mover6Error, ValueError, TypeError, ArithmeticError) as err:
        return short_text(str(err))
    return None


def make_set_callback(table: dict, node: Optional[Node] = None,
                      check_config: Optional[Callable] = None
                      ) -> Callable[[list], SetParametersResult]:
    """
    Return an ``on_set_parameters`` callback that refuses values ``table`` does not allow.

    One bad value refuses the whole set, with the reason; nothing changes. Each value is checked
    against its spec (``parameters.check_value``: type, length, finiteness, range, allowed
    values), then, with ``node`` and ``check_config`` (see ``declare``) and once every parameter
    of ``table`` is declared, the configuration the set would leave in force. Parameters not in
    the table (``use_sim_time`` ...) are left to rclpy.
    """
    def on_set_parameters(parameters):
        new = {}
        for parameter in parameters:
            spec = table.get(parameter.name)
            if spec is None:
                continue
            value = parameter.value
            if spec.type == 'float_list' and value is not None:
                value = list(value)       # rclpy gives an array.array
            try:
                check_value(spec, value)
            except InvalidInputError as err:
                return SetParametersResult(successful=False, reason=short_text(str(err)))
            new[parameter.name] = value
        if new and check_config is not None and all(node.has_parameter(n) for n in table):
            reason = whole_config_problem(
                check_config, lambda n: new[n] if n in new else node.get_parameter(n).value)
            if reason is not None:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)
    return on_set_parameters


def collision_settings(get: Callable[[str], object]) -> CollisionSettings:
    """
    Return the ``CollisionSettings`` of the collision parameters (planner or controller).

    Raises ``InvalidInputError`` for a tool size or keep-out boxes the checker cannot use: the
    nodes' ``check_config`` builds it, so such a set is refused before it is accepted.
    """
    return CollisionSettings(
        enabled=bool(get('collision_check')),
        tool=ToolVolume(get('tool_shape'), tuple(get('tool_size'))),
        table_margin=float(get('table_margin')), keep_out=tuple(get('keep_out_boxes')),
        max_joint_step=float(get('collision_step')))


def config_from_parameters(get: Callable[[str], object]) -> tuple[str, ControllerConfig]:
    """Return ``(limit_set, ControllerConfig)`` from a parameter getter ``get(name)``."""
    law = LawConfig(profile=get('profile'), lambda_max=get('lambda_max'), t_max=get('t_max'),
                    t_blend=get('t_blend'), a_max=get('a_max'), j_max=get('j_max'))
    config = ControllerConfig(
        law=law, goal_tolerance=get('goal_tolerance'), state_timeout=get('state_timeout'),
        position_gain=get('position_gain'), settle_timeout=get('settle_timeout'),
        path_tolerance=get('path_tolerance'), rate=get('rate'), jog_units=get('jog_units'),
        speed_override=get('speed_override'), driver_tick_size=tuple(get('driver_tick_size')),
        driver_cycle=get('driver_cycle'), cycle_driver=get('cycle_driver'),
        settle_tolerance=get('settle_tolerance'),
        settle_time=get('settle_time'), servo=servo_config_from_parameters(get))
    limit_set = get('limit_set')
    if limit_set not in LIMIT_SETS:
        raise InvalidInputError(f'limit_set must be one of {LIMIT_SETS}, got {limit_set!r}')
    return limit_set, config


def servo_config_from_parameters(get: Callable[[str], object]) -> ServoConfig:
    """Return the ``ServoConfig`` of the ``servo_*`` parameters (and ``a_max``)."""
    return ServoConfig(
        command_timeout=get('servo_command_timeout'), pose_gain=get('servo_pose_gain'),
        damping=get('servo_damping'),
        lower_singularity_threshold=get('servo_lower_singularity_threshold'),
        hard_stop_singularity_threshold=get('servo_hard_stop_singularity_threshold'),
        joint_limit_margin=get('servo_joint_limit_margin'), a_max=get('a_max'))


def planner_settings_from_parameters(get: Callable[[str], object]) -> PlannerSettings:
    """
    Return the ``PlannerSettings`` of a parameter getter ``get(name)``; raise when invalid.

    The set-parameters check builds it from the values a set would leave in force, so a value
    the planner could not plan with (a tool size, keep-out boxes) is refused at the set.
    """
    return PlannerSettings(
        n_waypoints=get('n_waypoints'), max_step=get('max_step'),
        max_angle_step=get('max_angle_step'), peak_height=get('peak_height'),
        max_joint_step=get('max_joint_step'), max_condition=get('max_condition'),
        position_tolerance=get('position_tolerance'),
        orientation_tolerance=get('orientation_tolerance'),
        collision=collision_settings(get))
