"""
The sim_bridge node's controls of the simulation: ~/reset_to, ~/reset, ~/pause and ~/step.

Each runs the physics steps due before it (``_catch_up``), so it acts at the present time, and
holds the node's ``step_lock`` and ``lock`` as the physics thread does. ``SimControls`` is a part
of ``bridge_node.SimBridgeNode`` (its state is the node's, set in ``SimBridgeNode.__init__``);
it is not used on its own.
"""

from mover6_control.errors import InvalidInputError
import numpy as np
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger


class SimControls:
    """The reset, pause and step callbacks of ``SimBridgeNode``; see the module docstring."""

    def on_reset_to(self, msg: JointState) -> None:
        """Reset to the positions of a JointState (by name; unnamed joints go home)."""
        names = list(msg.name)
        try:
            if len(msg.position) != len(names):
                raise InvalidInputError(
                    f'{len(names)} names but {len(msg.position)} positions')
            index = {name: i for i, name in enumerate(self.arm.joint_names)}
            unknown = [n for n in names if n not in index]
            if unknown:
                raise InvalidInputError(f'unknown joints {unknown}')
            q = self.sim.home_q.copy()
            for name, value in zip(names, msg.position):
                q[index[name]] = value
            self._reset(q)
        except InvalidInputError as exc:
            self.get_logger().warning(f'~/reset_to rejected: {exc}')

    def on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Reset to ``initial_q``, at rest, commands dropped."""
        self._reset(None)
        response.success = True
        response.message = f'reset to {np.round(self.sim.home_q, 4).tolist()}'
        return response

    def on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        """Pause (data true) or resume (data false) the physics."""
        with self.step_lock:
            self._catch_up()             # pause at the present time
            with self.lock:
                self.paused = bool(request.data)
                t = self.sim.time
        self._wake.set()
        response.success = True
        response.message = f'{"paused" if self.paused else "running"} at t = {t:.4f} s'
        self.get_logger().info(response.message)
        return response

    def on_step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """While paused, run one control period and publish; refuse when running."""
        if not self.paused:
            response.success = False
            response.message = 'not paused: ~/pause first'
            return response
        n = max(1, int(round(self.publish_period / self.dt)))
        with self.step_lock:
            for _ in range(n):
                self._one_step(publish_states=self.vendor)  # vendor: its one reading of the cycle
            if not self.vendor:                             # the state at the end of the period
                with self.lock:
                    reading = self.sim.state()
                    self._next_publish = reading.time + self.publish_period
                self._publish_state(reading)
        response.success = True
        response.message = f'stepped {n} x {self.dt} s to t = {self.sim.time:.4f} s'
        return response

    def _reset(self, q):
        """Reset the simulator (raises on a bad ``q``) and publish the new state at once."""
        with self.step_lock:
            self._catch_up()             # reset at the present time
            with self.lock:
                self.sim.reset(q)
                self._pending = None
                reading = self.sim.state()
            self._publish_state(reading)
        self.get_logger().info(f'reset to {np.round(reading.q, 4).tolist()}')
