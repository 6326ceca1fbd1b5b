"""
The recorder: the stack's topics into a rosbag2-layout MCAP file (``recorder/bag_writer.py``).

``ros2 run mover6_control recorder --ros-args -p path:=BAG`` (``./run.sh record [BAG]
[TOPICS...]``; on by default in ``./run.sh demo``). Records ``topics`` (default: /joint_states,
/JointJog, /joint_demands, the goals, both status topics, /tf, /tf_static, /diagnostics, the
simulator's contacts and /robot_description) as they appear in the graph: each topic is
subscribed once a publisher of it is seen, with that publisher's type, and with its durability
(a transient-local topic, such as the status topics, gives the recorder its last message) and
reliability, as ros2 bag does. Messages are written as they came off the wire (raw CDR), stamped
with their receive time.

Bad input: a path that cannot be written stops the node before it subscribes anything, with
the reason (exit code 1); the other nodes never notice. A write that fails while recording (the
disk is full) stops the recording with the reason on ``~/status`` and in the log; the node
stays up doing nothing else, so a launcher does not take the stack down with it. On shutdown
the file is finished and ``metadata.yaml`` written.
"""

import importlib
import time
from typing import Optional, Sequence

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.errors import InvalidInputError
from mover6_control.nodes.messages.conversions import make_status
from mover6_control.nodes.recorder.bag_writer import BagWriter
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.params import declare
from mover6_control.nodes.runtime.qos import STATUS_QOS
from mover6_control.parameters import RECORDER
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.topic_endpoint_info import TopicEndpointInfo
import yaml

DEPTH = 1000          # messages a subscription may queue while a write is slow


def message_class(type_name: str) -> type:
    """Return the Python class of ``pkg/msg/Type``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def default_path() -> str:
    """Return ros2 bag's default folder name, ``rosbag2_YYYY_MM_DD-HH_MM_SS``."""
    return time.strftime('rosbag2_%Y_%m_%d-%H_%M_%S')


def _time(duration):
    """Return rosbag2's {sec, nsec} of an rclpy ``Duration``."""
    sec, nsec = divmod(duration.nanoseconds, 10**9)
    return {'sec': int(sec), 'nsec': int(nsec)}


def qos_dict(qos: QoSProfile) -> dict:
    """Return one offered QoS profile as rosbag2's metadata (version 8) writes it."""
    return {'history': int(qos.history), 'depth': int(qos.depth),
            'reliability': int(qos.reliability), 'durability': int(qos.durability),
            'deadline': _time(qos.deadline), 'lifespan': _time(qos.lifespan),
            'liveliness': int(qos.liveliness),
            'liveliness_lease_duration': _time(qos.liveliness_lease_duration),
            'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions)}


def matching_qos(infos: Sequence[TopicEndpointInfo]) -> tuple[QoSProfile, str]:
    """
    Return (QoS, offered_qos_profiles text) that receives from every publisher in ``infos``.

    Transient local only when every publisher offers it (then the last message comes at once),
    reliable only when every publisher is.
    """
    latched = bool(infos) and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    qos = QoSProfile(
        depth=DEPTH,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT)
    text = yaml.safe_dump([qos_dict(i.qos_profile) for i in infos], sort_keys=False)
    return qos, text


class RecorderNode(Node):
    """Record the stack's topics; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('recorder', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node
        declare(self, RECORDER, guard=self.guard)
        path = self.get_parameter('path').value or default_path()
        self.wanted = [self.resolve_topic_name(t)
                       for t in self.get_parameter('topics').value.split()]
        if not self.wanted:
            raise InvalidInputError('recorder: no topics to record')
        self.bag = BagWriter(path)           # raises before anything is subscribed
        self.stopped = ''                    # why the recording stopped ('' while it runs)
        self.subscriptions_by_topic = {}
        self.pub_status = self.create_publisher(DiagnosticStatus, '~/status', STATUS_QOS)
        self.guard.timer(self.get_parameter('discovery_period').value, self.discover)
        self.guard.timer(1.0, self.publish_status)
        self.get_logger().info(f'recording {len(self.wanted)} topics into {self.bag.path}')
        self.discover()
        self.publish_status()

    def discover(self) -> None:
        """Subscribe every wanted topic that has a publisher now."""
        if self.stopped:
            return
        types = dict(self.get_topic_names_and_types())
        for topic in self.wanted:
            if topic in self.subscriptions_by_topic or topic not in types:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            type_name = types[topic][0]
            qos, qos_text = matching_qos(infos)
            try:
                self.bag.add_topic(topic, type_name, qos_text)
                kind = message_class(type_name)
            except (InvalidInputError, ImportError, AttributeError, ValueError) as err:
                self.get_logger().warning(f'{topic} ({type_name}) is not recorded: {err}')
                self.subscriptions_by_topic[topic] = None
                continue
            except OSError as err:
                self.stop(f'recording stopped: {err}')
                return
            self.subscriptions_by_topic[topic] = self.guard.subscription(
                kind, topic, lambda data, topic=topic: self.on_message(topic, data), qos,
                raw=True)

    def on_message(self, topic: str, data: bytes) -> None:
        """Write one message (its CDR bytes as received)."""
        if self.stopped:
            return
        try:
            self.bag.write(topic, data, time.time_ns())
        except OSError as err:
            self.stop(f'recording stopped: {err}')

    def stop(self, reason: str) -> None:
        """Stop recording for ``reason``: no more subscriptions, the file closed as it can be."""
        if self.stopped:
            return
        self.stopped = reason
        for sub in self.subscriptions_by_topic.values():
            if sub is not None:
                self.destroy_subscription(sub)
        self.subscriptions_by_topic = dict.fromkeys(self.subscriptions_by_topic)
        try:
            self.bag.close()
        except OSError as err:
            self.stopped = f'{reason}; closing the file: {err}'
        self.get_logger().error(f'{self.stopped} ({self.bag.message_count} messages written '
                                f'to {self.bag.path})')
        self.publish_status()

    def publish_status(self) -> None:
        """Publish ``~/status``: recording (OK) or stopped (ERROR, with the reason)."""
        values = {'path': self.bag.path, 'messages': self.bag.message_count,
                  'topics': ' '.join(t for t, s in self.subscriptions_by_topic.items() if s)}
        if self.stopped:
            self.pub_status.publish(make_status('recorder', 'ERROR', self.stopped, values))
        else:
            self.pub_status.publish(make_status('recorder', 'OK', 'recording', values))

    def destroy_node(self) -> None:
        """Finish the recording (file summary, metadata.yaml), then destroy the node."""
        if not self.stopped:
            try:
                self.bag.close()
                self.get_logger().info(f'recorded {self.bag.message_count} messages into '
                                       f'{self.bag.path}')
            except OSError as err:
                self.get_logger().error(f'closing the recording: {err}')
        return super().destroy_node()


def main(args: Optional[list[str]] = None) -> None:
    """Record until Ctrl-C; a path that cannot be written stops it at once with the reason."""
    try:
        shutdown.run_node(RecorderNode, args)
    except InvalidInputError as err:
        raise SystemExit(f'recorder: {err}')


if __name__ == '__main__':
    main()
