"""
The sim_bridge node's controls of the simulation, without ROS: reset, pause and step.

``bridge_node.SimBridgeNode``'s service and topic callbacks (~/reset_to, ~/reset, ~/pause,
~/step) take the request apart and call a ``SimControls``. It is built on the node's
``PhysicsThread`` (the simulator, its locks and its outputs) and the arm's joint names; each
control first runs the physics steps due before it (``PhysicsThread.catch_up``), so it acts at
the present time, and holds ``step_lock`` and ``lock`` as the physics thread does. A test builds
one on a ``PhysicsThread`` that is not started.
"""

from typing import Any, Optional, Sequence

from mover6_control.errors import InvalidInputError
import numpy as np


class SimControls:
    """Reset, pause and step of the bridge's simulation; see the module docstring."""

    def __init__(self, physics: Any, joint_names: Sequence[str], logger: Any):
        """Control ``physics`` (a ``PhysicsThread``) of an arm with ``joint_names``."""
        self.physics = physics
        self.index = {name: i for i, name in enumerate(joint_names)}
        self.logger = logger

    def named_positions(self, names: Sequence[str], positions: Sequence[float]) -> np.ndarray:
        """Return ``initial_q`` with the named joints at ``positions``; raise on a bad name."""
        if len(positions) != len(names):
            raise InvalidInputError(f'{len(names)} names but {len(positions)} positions')
        unknown = [n for n in names if n not in self.index]
        if unknown:
            raise InvalidInputError(f'unknown joints {unknown}')
        q = self.physics.sim.home_q.copy()
        for name, value in zip(names, positions):
            q[self.index[name]] = value
        return q

    def reset_to(self, q: Optional[np.ndarray]) -> None:
        """Reset to ``q`` (None: ``initial_q``) at rest, commands dropped; publish the state."""
        physics = self.physics
        with physics.step_lock:
            physics.catch_up()           # reset at the present time
            with physics.lock:
                physics.sim.reset(q)     # raises on a bad q, changing nothing
                physics.pending = None
                reading = physics.sim.state()
            physics.out.publish_state(reading)
        self.logger.info(f'reset to {np.round(reading.q, 4).tolist()}')

    def pause(self, paused: bool) -> float:
        """Pause (True) or resume (False) the physics at the present time; return sim time."""
        physics = self.physics
        with physics.step_lock:
            physics.catch_up()           # pause at the present time
            with physics.lock:
                physics.paused = paused
                t = physics.sim.time
        physics.wake.set()
        return t

    def step_period(self) -> int:
        """
        Run one control period of physics steps (the caller checks ``paused``); return them.

        One /joint_states period, published at its end; in vendor mode one driver cycle, which
        publishes its own reading.
        """
        physics, pacing = self.physics, self.physics.pacing
        n = max(1, int(round(pacing.publish_period / pacing.dt)))
        with physics.step_lock:
            for _ in range(n):
                physics.one_step(publish_states=pacing.vendor)   # vendor: its one reading
            if not pacing.vendor:                                # the state at the period's end
                with physics.lock:
                    reading = physics.sim.state()
                    physics.next_publish = reading.time + pacing.publish_period
                physics.out.publish_state(reading)
        return n
