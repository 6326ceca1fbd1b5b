"""
The package's own robot state publisher: /robot_description, /tf and /tf_static for RViz.

What ``robot_state_publisher`` does, for installs that have none (the PyPI wheels): publishes
the URDF (parameter ``robot_description``, empty = the shipped config/mover6.urdf) on
/robot_description (std_msgs/String, transient local), the fixed joints once on /tf_static
(tf2_msgs/TFMessage, transient local) and, for every measured /joint_states, the transform of
each moving joint the message names on /tf (stamped with the message's stamp, at most
``publish_frequency`` times a second), every frame id with ``frame_prefix``. The launchers start
the real robot_state_publisher where the ROS install has it, this node otherwise.

The transforms come from ``kinematics.urdf_tree`` (the URDF's own tree, every link); a test
checks the flange's chain against the package's forward kinematics.
"""

import math
import os
from typing import Optional

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.rotations import matrices_to_quaternions
from mover6_control.kinematics.urdf_tree import fixed_transforms, moving_transforms, parse_urdf
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.node_clock import now_ns
from mover6_control.nodes.runtime.params import declare
from mover6_control.nodes.runtime.qos import LATCHED_QOS
from mover6_control.parameters import STATE_PUBLISHER
from mover6_control.resources import CONFIG_DIR
import numpy as np
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

SHIPPED_URDF = os.path.join(CONFIG_DIR, 'mover6.urdf')


def make_transform_stamped(T: np.ndarray, parent: str, child: str, stamp: Time,
                           prefix: str = '') -> TransformStamped:
    """
    Return the ``TransformStamped`` of ``T`` (4, 4) from ``parent`` to ``child``.

    ``T`` is a transform of the URDF tree (checked when the URDF was parsed): not checked again.
    """
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = prefix + parent
    msg.child_frame_id = prefix + child
    t = msg.transform.translation
    t.x, t.y, t.z = T[:3, 3].tolist()
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = matrices_to_quaternions(T[:3, :3]).tolist()
    return msg


def shipped_description() -> str:
    """Return the text of the shipped URDF (config/mover6.urdf)."""
    with open(SHIPPED_URDF) as f:
        return f.read()


class StatePublisherNode(Node):
    """Publish the robot description and its transforms; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('state_publisher', **kwargs)
        self.guard = CallbackGuard(self)     # a malformed message is refused, the node goes on
        declare(self, STATE_PUBLISHER, guard=self.guard)
        self.description = self.get_parameter('robot_description').value or shipped_description()
        self.tree = parse_urdf(self.description)
        self.joint_names = {j.name for j in self.tree.moving}
        self.prefix = self.get_parameter('frame_prefix').value
        self.last_publish = None        # [ns] of the node clock
        self.period_ns = self.frequency_period_ns()
        self.guard.after_set(lambda _: setattr(self, 'period_ns', self.frequency_period_ns()))
        self.published = 0
        self.pub_description = self.create_publisher(String, 'robot_description', LATCHED_QOS)
        self.pub_static = self.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        self.pub_tf = self.create_publisher(TFMessage, '/tf', 100)
        self.pub_description.publish(String(data=self.description))
        now = self.get_clock().now().to_msg()
        self.pub_static.publish(TFMessage(transforms=[
            make_transform_stamped(T, j.parent, j.child, now, self.prefix)
            for j, T in fixed_transforms(self.tree)]))
        # Raw: a message is deserialized only when /tf is due (at most publish_frequency), not
        # at the 100 Hz of /joint_states (the planner reads its states the same way).
        self.guard.subscription(JointState, 'joint_states', self.on_joint_states, 10, raw=True)
        self.get_logger().info(
            f'{self.tree.name}: {len(self.tree.moving)} moving and {len(self.tree.fixed)} fixed '
            f'joints from {self.tree.root}')

    def frequency_period_ns(self) -> int:
        """Return the shortest time [ns] between two /tf messages (``publish_frequency``)."""
        return round(1e9 / self.get_parameter('publish_frequency').value)

    def on_joint_states(self, data: bytes) -> None:
        """
        Publish /tf for the joints a message names (at most ``publish_frequency`` a second).

        A message with unequal name and position counts, or a non-finite position of a joint
        of the tree, is refused (``InvalidInputError``, through the guard): no /tf from it.
        """
        # 100 messages a second, most of them dropped here: no Time object, no parameter read.
        now = now_ns(self.get_clock())
        if self.last_publish is not None and now - self.last_publish < self.period_ns:
            return
        msg = deserialize_message(data, JointState)
        if len(msg.position) != len(msg.name):   # robot_state_publisher, too, drops it
            raise InvalidInputError(f'/joint_states has {len(msg.name)} names but '
                                    f'{len(msg.position)} positions')
        positions = dict(zip(msg.name, msg.position))
        bad = [n for n in self.joint_names if n in positions and not math.isfinite(positions[n])]
        if bad:
            raise InvalidInputError(f'/joint_states has non-finite positions of {bad}')
        stamp = msg.header.stamp
        if stamp.sec == 0 and stamp.nanosec == 0:
            stamp = Time(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000)
        transforms = [make_transform_stamped(T, j.parent, j.child, stamp, self.prefix)
                      for j, T in moving_transforms(self.tree, positions)]
        if transforms:
            self.pub_tf.publish(TFMessage(transforms=transforms))
            self.last_publish = now
            self.published += 1


def main(args: Optional[list[str]] = None) -> None:
    """Run the state publisher until Ctrl-C (a bad description stops it with the reason)."""
    try:
        shutdown.run_node(StatePublisherNode, args)
    except InvalidInputError as err:
        raise SystemExit(f'state_publisher: {err}')


if __name__ == '__main__':
    main()
