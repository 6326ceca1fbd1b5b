"""
The console's goal panel: the goal, its via poses, shape and profile; Plan, Go and Stop.

The goal is a draggable gizmo and six numbers (X Y Z A B C in the Mover6 report's convention),
kept in step; the answer to the latest action is shown under the buttons. The numbers are text
fields: viser's number field drops a leading minus sign as it is typed (an empty or partial
number is not taken), so a goal at negative Y could not be typed into it.
"""

from dataclasses import dataclass
from typing import Any, Callable

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import quaternion_to_matrix
from mover6_control.nodes.console.collision_scene import wxyz
from mover6_control.nodes.console.page_logic import GoalConvention, GoalRoute, SHAPES
from mover6_control.parameters import PROFILES
import numpy as np
from viser import ViserServer

LABELS = ('X [m]', 'Y [m]', 'Z [m]', 'A [rad]', 'B [rad]', 'C [rad]')
DEFAULT_PROFILE = "controller's"      # the controller's ``profile`` parameter
START = (0.30, 0.05, 0.36, 0.0, 0.0, 0.0)   # the README's first goal from home
GIZMO_SCALE = 0.12


@dataclass(frozen=True)
class GoalRequest:
    """A goal as the page gives it: pose (4, 4), its numbers, shape, profile ('' default), vias."""

    T: np.ndarray
    numbers: tuple
    shape: str
    profile: str
    vias: tuple

    @property
    def route(self) -> GoalRoute:
        """Return where the goal goes (raises for a shape that does not fit the vias)."""
        return GoalRoute.of(self.shape, len(self.vias))


class GoalPanel:
    """The goal's controls; ``on_plan``, ``on_go`` (a ``GoalRequest``) and ``on_stop()``."""

    def __init__(self, server: ViserServer, convention: GoalConvention, on_plan: Callable,
                 on_go: Callable, on_stop: Callable, wrap: Callable):
        """Build the controls; every callback goes through ``wrap(source, fn)`` (the guard)."""
        self.server = server
        self.convention = convention
        self.vias = []
        self.via_frames = []
        gui = server.gui
        with gui.add_folder('Goal (X Y Z A B C, the Mover6 report)'):
            self.numbers = [gui.add_text(label, f'{v:g}') for label, v in zip(LABELS, START)]
            self.shape = gui.add_dropdown('Shape', SHAPES, initial_value='linear')
            self.profile = gui.add_dropdown('Profile', (DEFAULT_PROFILE,) + tuple(PROFILES),
                                            initial_value=DEFAULT_PROFILE)
            self.vias_text = gui.add_markdown('Via poses: none')
            add_via = gui.add_button('Add via (this pose)')
            clear_vias = gui.add_button('Clear vias')
            plan = gui.add_button('Plan', color='blue')
            go = gui.add_button('Go', color='green')
            stop = gui.add_button('Stop', color='red')
            self.answer = gui.add_markdown('Answer: -')
        self.gizmo = server.scene.add_transform_controls('/goal', scale=GIZMO_SCALE)
        self.show_numbers_on_gizmo()
        for handle in self.numbers:
            handle.on_update(wrap('console goal numbers', self.on_numbers))
        self.gizmo.on_update(wrap('console goal gizmo', self.on_gizmo))
        add_via.on_click(wrap('console add via', lambda _: self.add_via()))
        clear_vias.on_click(wrap('console clear vias', lambda _: self.clear_vias()))
        plan.on_click(wrap('console plan', lambda _: on_plan(self.request())))
        go.on_click(wrap('console go', lambda _: on_go(self.request())))
        stop.on_click(wrap('console stop', lambda _: on_stop()))

    def values(self) -> tuple:
        """Return the six numbers; raise ``InvalidInputError`` for a field that is not one."""
        numbers = []
        for label, handle in zip(LABELS, self.numbers):
            try:
                numbers.append(float(handle.value))
            except ValueError:
                raise InvalidInputError(f'{label} is not a number: {handle.value!r}') from None
        return tuple(numbers)

    def request(self) -> GoalRequest:
        """Return the goal the page shows; raise ``InvalidInputError`` for one that is not."""
        numbers = self.values()
        T = self.convention.pose(numbers)
        profile = '' if self.profile.value == DEFAULT_PROFILE else str(self.profile.value)
        request = GoalRequest(T, numbers, str(self.shape.value), profile, tuple(self.vias))
        request.route        # a shape that does not fit the via poses is refused here
        return request

    def set_numbers(self, numbers: tuple) -> None:
        """Show ``numbers`` (X Y Z A B C) in the fields and on the gizmo."""
        self.show_numbers(numbers)
        self.show_numbers_on_gizmo()

    def show_numbers(self, numbers: tuple) -> None:
        """Write ``numbers`` into the fields (4 decimals)."""
        for handle, value in zip(self.numbers, numbers):
            handle.value = f'{float(value):.4f}'

    def show_numbers_on_gizmo(self) -> None:
        """Put the gizmo at the pose of the numbers."""
        T = self.convention.pose(self.values())
        self.gizmo.position = T[:3, 3]
        self.gizmo.wxyz = wxyz(T[:3, :3])

    def on_numbers(self, event: Any) -> None:
        """Move the gizmo to the numbers typed in the page (a partial number: not yet)."""
        if event.client is None:
            return
        try:
            self.show_numbers_on_gizmo()
        except InvalidInputError:
            pass         # being typed ('-', '0.'): Plan and Go say what is wrong with it

    def on_gizmo(self, _event: Any) -> None:
        """Show the dragged gizmo's pose in the numbers (angles nearest the ones shown)."""
        w, x, y, z = self.gizmo.wxyz
        T = np.eye(4)
        T[:3, :3] = quaternion_to_matrix([x, y, z, w])
        T[:3, 3] = self.gizmo.position
        try:
            ref = self.values()[3:]
        except InvalidInputError:
            ref = (0.0, 0.0, 0.0)
        self.show_numbers(self.convention.numbers(T, ref))

    def add_via(self) -> None:
        """Take the pose shown as the next via pose."""
        T = self.convention.pose(self.values())
        self.vias.append(T)
        self.via_frames.append(self.server.scene.add_frame(
            f'/vias/{len(self.vias)}', axes_length=0.03, axes_radius=0.002,
            position=T[:3, 3], wxyz=wxyz(T[:3, :3])))
        self.show_vias()

    def clear_vias(self) -> None:
        """Forget every via pose."""
        for frame in self.via_frames:
            frame.remove()
        self.vias, self.via_frames = [], []
        self.show_vias()

    def show_vias(self) -> None:
        """Say how many via poses there are, and where."""
        if not self.vias:
            self.vias_text.content = 'Via poses: none'
            return
        rows = [' '.join(f'{v:.3f}' for v in self.convention.numbers(T)) for T in self.vias]
        listed = '\n'.join(f'{k + 1}. `{r}`' for k, r in enumerate(rows))
        self.vias_text.content = f'Via poses:\n{listed}'

    def say(self, text: str) -> None:
        """Show the answer to the latest goal (Plan, Go, Stop)."""
        self.answer.content = f'Answer: {text}'
