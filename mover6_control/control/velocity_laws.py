"""
The names ``controller_core`` and the nodes import from here, at their new homes.

The velocity laws were split by concept: the profiles and their settings
(``control.profiles``), the plan and its segments (``control.motion_plan``), the planners of
the profiles (``control.planners``) and the command of a tick (``control.commands``). New code
imports from those modules; this one only keeps the imports of ``controller_core``,
``nodes.controller_node`` and ``nodes.planner_node`` working while they change elsewhere.
"""

from mover6_control.control.commands import (  # noqa: F401
    dead_zone_command, driver_velocity_limits, guard_position_limits, JOG_UNITS, min_jog_speed,
    tick_pulse_command, to_jog_units)
from mover6_control.control.motion_plan import MotionPlan, plan_stop  # noqa: F401
from mover6_control.control.planners import predicted_duration  # noqa: F401
from mover6_control.control.profiles import LawConfig  # noqa: F401
