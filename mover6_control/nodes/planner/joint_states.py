"""
The planner's latest /joint_states: kept as they came, converted when a goal needs them.

``keep`` stores the serialized message with its arrival time and does nothing else:
deserialising and mapping 100 messages a second to keep one cost more CPU than the rest of the
idle planner. ``current_q`` converts the latest when a goal is planned (a malformed latest
message refuses the goal); ``q`` says whether there are valid ones (the planner's readiness).
"""

import threading
from typing import Callable, Optional

from mover6_control.errors import Mover6Error
from mover6_control.kinematics.arm import ArmModel
from mover6_control.nodes.messages import conversions
import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState


class LatestJointStates:
    """The latest /joint_states of ``arm``'s joints (module docstring)."""

    def __init__(self, arm: ArmModel, now_ns: Callable[[], int]):
        """Keep states for ``arm``; ``now_ns()`` is the node clock [ns]."""
        self.arm = arm
        self.now_ns = now_ns
        self.came = threading.Event()   # set by every message
        self.latest = None       # (serialized /joint_states, node clock [ns] at arrival)
        self._converted = None   # (serialized message, its positions): the latest converted

    def keep(self, raw: bytes) -> None:
        """Keep ``raw`` (a serialized JointState) as the latest, with its arrival time."""
        self.latest = (raw, self.now_ns())
        if not self.came.is_set():     # set already: the same (and no lock taken)
            self.came.set()

    def positions(self, raw: bytes) -> np.ndarray:
        """Return the joint positions [rad] of a serialized JointState; raise when malformed."""
        if self._converted is None or self._converted[0] is not raw:
            msg = deserialize_message(raw, JointState)
            try:
                q, _ = conversions.joint_state_from_msg(msg, self.arm.joint_names)
            except Mover6Error as err:
                raise Mover6Error(f'the latest /joint_states is malformed ({err}): '
                                  'the current pose is unknown') from err
            self._converted = (raw, q)
        return self._converted[1]

    @property
    def q(self) -> Optional[np.ndarray]:
        """Return the latest joint positions (6,) [rad], or None (none yet, or malformed)."""
        latest = self.latest
        try:
            return None if latest is None else self.positions(latest[0])
        except Mover6Error:
            return None

    def current_q(self, timeout: float) -> np.ndarray:
        """Return the latest positions; raise when there are none or older than ``timeout``."""
        latest = self.latest
        if latest is None:
            raise Mover6Error('no /joint_states received yet: the current pose is unknown')
        raw, arrival = latest
        age = (self.now_ns() - arrival) * 1e-9
        if age > timeout:
            raise Mover6Error(f'/joint_states are {age:.2f} s old (limit {timeout:.2f} s): '
                              'the current pose is uncertain')
        return self.positions(raw).copy()
