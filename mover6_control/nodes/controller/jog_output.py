"""
The controller's /JointJog: one command a tick, written as bytes, and the zero that holds the arm.

All six joints, stamped with the node clock, velocities only; serialized by
``cdr.JointJogWriter`` (no message object per tick). The vendor driver keeps the last
command forever, so the node sends a zero when a tick fails and when it closes.
"""

from typing import Callable, Sequence

from mover6_control.nodes.messages import cdr
from rclpy.duration import Duration
from rclpy.publisher import Publisher


class JogOutput:
    """Publish the commands of the ticks on ``publisher`` (module docstring)."""

    def __init__(self, publisher: Publisher, joint_names: Sequence[str],
                 now_ns: Callable[[], int]):
        """Write JointJogs for ``joint_names`` on ``publisher``; ``now_ns`` stamps a zero."""
        self.publisher = publisher
        self.joint_names = list(joint_names)
        self.writer = cdr.JointJogWriter(self.joint_names)
        self.now_ns = now_ns

    def publish(self, stamp_ns: int, velocities: Sequence[float]) -> None:
        """Publish the velocities of one tick, stamped ``stamp_ns`` [ns] (node clock)."""
        self.publisher.publish(self.writer.serialize(*divmod(stamp_ns, 1_000_000_000),
                                                     velocities))

    def send_zero(self) -> None:
        """Publish a zero JointJog (the vendor driver keeps the last command forever)."""
        self.publish(self.now_ns(), [0.0] * len(self.joint_names))

    def wait_for_all_acked(self, timeout: float) -> None:
        """Wait up to ``timeout`` [s] for the readers to acknowledge what was sent."""
        self.publisher.wait_for_all_acked(Duration(seconds=timeout))
