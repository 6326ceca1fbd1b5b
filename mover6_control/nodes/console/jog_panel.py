"""
The console's jog panel: a slider per joint (JointJog) and a Cartesian pad (twist).

A command lasts while it is given (``JogHold``): a slider moved or a pad button pressed gives it
again; left alone, the command ends and the arm stops (released = stop). "Stop jog" ends it at
once and puts the sliders back to zero.
"""

from typing import Any, Callable

from mover6_control.nodes.console.page_logic import JogHold
import numpy as np
from viser import ViserServer

JOINT_SPEED = 0.3          # [rad/s] a slider's end
LINEAR_SPEED = 0.03        # [m/s] of a pad button
ANGULAR_SPEED = 0.2        # [rad/s] of a pad button
SLIDER_HOLD = 0.6          # [s] a slider's command lasts after its last move
PAD_HOLD = 0.4             # [s] a pad button's command lasts after its press
PAD = (('+X', 0, 1), ('-X', 0, -1), ('+Y', 1, 1), ('-Y', 1, -1), ('+Z', 2, 1), ('-Z', 2, -1),
       ('+Rx', 3, 1), ('-Rx', 3, -1), ('+Ry', 4, 1), ('-Ry', 4, -1), ('+Rz', 5, 1), ('-Rz', 5, -1))


class JogPanel:
    """The jog controls; ``due(now)`` returns the (joint, twist) commands to send now."""

    def __init__(self, server: ViserServer, joint_names: tuple, wrap: Callable,
                 clock: Callable[[], float]):
        """Build the sliders and the pad; ``clock()`` [s] times the commands."""
        self.clock = clock
        self.joints = JogHold(len(joint_names), SLIDER_HOLD)
        self.twist = JogHold(6, PAD_HOLD)      # linear x y z [m/s], angular x y z [rad/s]
        gui = server.gui
        with gui.add_folder('Jog', expand_by_default=False):
            self.sliders = [gui.add_slider(f'{name} [rad/s]', -JOINT_SPEED, JOINT_SPEED, 0.01,
                                           0.0) for name in joint_names]
            self.frame = gui.add_dropdown('Pad frame', ('base_link', 'link6'),
                                          initial_value='base_link')
            pad = gui.add_button_group('Pad (held while pressed again)',
                                       [label for label, _, _ in PAD])
            stop = gui.add_button('Stop jog', color='red')
        for slider in self.sliders:
            slider.on_update(wrap('console jog slider', self.on_slider))
        pad.on_click(wrap('console jog pad', lambda event: self.press(event.target.value)))
        stop.on_click(wrap('console jog stop', lambda _: self.stop()))

    def on_slider(self, event: Any) -> None:
        """Jog the joints at the sliders' speeds (a slider moved in the page)."""
        if event.client is not None:
            self.joints.give([s.value for s in self.sliders], self.clock())

    def press(self, label: str) -> None:
        """Move along (or about) the axis of the pad button pressed."""
        row = {name: (axis, sign) for name, axis, sign in PAD}[label]
        twist = np.zeros(6)
        speed = LINEAR_SPEED if row[0] < 3 else ANGULAR_SPEED
        twist[row[0]] = row[1] * speed
        self.twist.give(twist, self.clock())

    def stop(self) -> None:
        """End every jog command now; the sliders back to zero."""
        self.joints.release()
        self.twist.release()
        for slider in self.sliders:
            slider.value = 0.0

    def due(self, now: float) -> tuple:
        """Return (joint velocities or None, twist or None, frame) to send at ``now`` [s]."""
        joints = self.joints.due(now)
        if joints is None and any(s.value for s in self.sliders) and now >= self.joints.until:
            for slider in self.sliders:    # released: the sliders show the stop
                slider.value = 0.0
        return joints, self.twist.due(now), str(self.frame.value)
