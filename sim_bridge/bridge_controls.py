"""
The sim_bridge node's controls of the simulation, without ROS: reset, pause and step.

``bridge_node.SimBridgeNode``'s service and topic callbacks (~/reset_to, ~/reset, ~/pause,
~/step) take the request apart and call these. Each runs the physics steps due before it
(``_catch_up``), so it acts at the present time, and holds the node's ``step_lock`` and ``lock``
as the physics thread does. ``SimControls`` is a part of ``SimBridgeNode`` (its state is the
node's, set in ``SimBridgeNode.__init__``); it is not used on its own.
"""

from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
import numpy as np


class SimControls:
    """Reset, pause and step of ``SimBridgeNode``'s simulation; see the module docstring."""

    def named_positions(self, names: Sequence[str], positions: Sequence[float]) -> np.ndarray:
        """Return ``initial_q`` with the named joints at ``positions``; raise on a bad name."""
        if len(positions) != len(names):
            raise InvalidInputError(f'{len(names)} names but {len(positions)} positions')
        index = {name: i for i, name in enumerate(self.arm.joint_names)}
        unknown = [n for n in names if n not in index]
        if unknown:
            raise InvalidInputError(f'unknown joints {unknown}')
        q = self.sim.home_q.copy()
        for name, value in zip(names, positions):
            q[index[name]] = value
        return q

    def reset_to(self, q: Optional[np.ndarray]) -> None:
        """Reset to ``q`` (None: ``initial_q``) at rest, commands dropped; publish the state."""
        with self.step_lock:
            self._catch_up()             # reset at the present time
            with self.lock:
                self.sim.reset(q)        # raises on a bad q, changing nothing
                self._pending = None
                reading = self.sim.state()
            self._publish_state(reading)
        self.get_logger().info(f'reset to {np.round(reading.q, 4).tolist()}')

    def pause(self, paused: bool) -> float:
        """Pause (True) or resume (False) the physics at the present time; return sim time."""
        with self.step_lock:
            self._catch_up()             # pause at the present time
            with self.lock:
                self.paused = paused
                t = self.sim.time
        self._wake.set()
        return t

    def step_period(self) -> int:
        """
        Run one control period of physics steps (the caller checks ``paused``); return them.

        One /joint_states period, published at its end; in vendor mode one driver cycle, which
        publishes its own reading.
        """
        n = max(1, int(round(self.publish_period / self.dt)))
        with self.step_lock:
            for _ in range(n):
                self._one_step(publish_states=self.vendor)  # vendor: its one reading of the cycle
            if not self.vendor:                             # the state at the end of the period
                with self.lock:
                    reading = self.sim.state()
                    self._next_publish = reading.time + self.publish_period
                self._publish_state(reading)
        return n
