"""
Node parameters from ``mover6_control.parameters``: descriptors, declaration, the set check.

The one place where a ``ParameterSpec`` becomes a ROS ``ParameterDescriptor`` (description with
the unit, ``floating_point_range`` / ``integer_range``, allowed values as
``additional_constraints``, ``read_only``), used by every node alike. The configs the nodes
build from their parameters are in ``node_configs``: this module imports no core config, so a
node that needs none (the bridge, the state publisher) does not load the planners to start.
"""

from typing import Callable, Optional

from mover6_control.errors import InvalidInputError, Mover6Error
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.parameters import check_value, ParameterSpec
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


def declare(node: Node, table: dict, check_config: Optional[Callable] = None, *,
            guard: CallbackGuard) -> Callable:
    """
    Declare every parameter of ``table`` on ``node`` and refuse invalid values from then on.

    ``check_config(get)``, when given, builds the node's whole configuration from a getter
    ``get(name)`` and raises when it is invalid (the relations between parameters: a capsule
    tool at least as long as wide, a stop threshold above its slow-down threshold ...); a set is
    checked with it on the values it would leave in force, before it is accepted, so a node's
    after-set callback applies only what this check built successfully. The set-parameters
    check is in place before the declarations, and the start values are checked as a whole once
    all are declared, so a bad start value (from a parameter file or ``-p``) stops the node
    too. Raises ``InvalidInputError`` (a ValueError) saying why. The check is added through the
    node's ``guard`` (``callback_guard``): one that raises refuses the set, the node goes on.
    """
    callback = guard.set_check(make_set_callback(table, node, check_config))
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
