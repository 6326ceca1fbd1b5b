"""
The configs the controller and the planner build from their parameters.

The controller's, its servo's, the planner's, and the collision settings both of them use.

Each takes a getter ``get(name)`` of the parameter values (those in force, or those a set would
leave in force: the set check builds the config to refuse a value the node could not use) and
raises ``InvalidInputError`` for one it cannot use. No ROS here: ``params`` declares the
parameters, this module reads them.
"""

from typing import Callable, Optional

from mover6_control.collision.checker import CollisionSettings
from mover6_control.collision.geometry import ToolVolume
from mover6_control.collision.standing import StandingCheck
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.profiles import LawConfig
from mover6_control.control.servo import ServoConfig
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import LIMIT_SETS, mover6
from mover6_control.parameters import SIM_BRIDGE
from mover6_control.planning.planner_core import PlannerSettings


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


def standing_check() -> StandingCheck:
    """
    Return the ``StandingCheck`` of the Mover6, at its start configuration before any states.

    The start configuration is the simulator's start and home configuration (``initial_q``'s
    default); the joint limits do not change the arm's shapes.
    """
    return StandingCheck(mover6(), [SIM_BRIDGE['initial_q'].default])


def check_where_it_stands(standing: StandingCheck, get: Callable[[str], object],
                          q_now: Optional[object],
                          in_force: Optional[Callable[[str], object]]) -> None:
    """
    Raise ``InvalidInputError`` when the collision parameters of ``get`` collide the arm.

    The planner's and the controller's one check of their collision parameters against where
    the arm stands (``collision.standing``): ``q_now`` the latest joint positions (None: none
    yet), ``in_force`` the getter of the parameters in force (None: at start, none in force).
    """
    standing.check(collision_settings(get), q_now,
                   None if in_force is None else collision_settings(in_force))


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
