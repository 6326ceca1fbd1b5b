"""
The planner's settings as the console follows them: asked from the planner every ``PERIOD``.

"Plan" plans with them and the collision scene draws what they make the checker collide; until
the planner answers, the defaults of its parameter table stand.
"""

from typing import Callable

from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.console.page_logic import Preview
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_configs import planner_settings_from_parameters
from mover6_control.parameters import PLANNER
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.task import Future

PERIOD = 2.0      # [s] the planner's parameters asked again


class PlannerSettingsFollower:
    """The planner's parameters, its arm (limit set) and the ``Preview`` planning with them."""

    def __init__(self, node: Node, guard: CallbackGuard, planner: str, on_change: Callable):
        """Ask ``planner`` (a node name) through ``node``; ``on_change(self)`` after a change."""
        self.guard = guard
        self.on_change = on_change
        self.values = {name: spec.default for name, spec in PLANNER.items()}
        self.settings = planner_settings_from_parameters(self.values.get)
        self.arm = mover6(self.values['limit_set'])
        self.preview = Preview(self.arm)
        self.client = node.create_client(GetParameters, f'{planner}/get_parameters')
        guard.timer(PERIOD, self.ask)

    @property
    def frame_id(self) -> str:
        """Return the frame the planner takes goals in."""
        return str(self.values['frame_id'])

    def ask(self) -> None:
        """Ask the planner for its parameters (when it is there)."""
        if not self.client.service_is_ready():
            return
        future = self.client.call_async(GetParameters.Request(names=list(PLANNER)))
        future.add_done_callback(self.guard.wrap('planner parameters', self.on_answer))

    def on_answer(self, future: Future) -> None:
        """Take the planner's parameters; refuse (the guard) values it could not plan with."""
        response = future.result()
        if response is None or len(response.values) != len(PLANNER):
            return
        values = {name: parameter_value_to_python(value)
                  for name, value in zip(PLANNER, response.values)}
        settings = planner_settings_from_parameters(values.get)
        if values == self.values:
            return
        if values['limit_set'] != self.values['limit_set']:
            self.arm = mover6(values['limit_set'])
            self.preview = Preview(self.arm)
        self.values, self.settings = values, settings
        self.on_change(self)
