"""
RViz markers of what the planner works with: the goal, the planned tool path, table, keep-out.

Publishes ``markers`` (visualization_msgs/MarkerArray, transient local: RViz opened later gets
the last set) in ``frame_id`` (base_link, with ``frame_prefix``), one namespace each:

- ``table``: the plane z = 0 the arm stands on (a thin slab ``table_size`` across) and, above
  it, the ``table_margin`` every part of the arm keeps;
- ``keep_out``: each keep-out box (red, translucent);
- ``goal``: the last /pose_goal (or /path_goal's goal) as the flange's axes, its via poses as
  spheres;
- ``planned_path``: the tool (flange) path of the last /joint_demands, by forward kinematics of
  every waypoint.

The table margin and keep-out boxes are the planner's (``planner_node``): read from it at start
and followed through /parameter_events, so the markers show what the collision check uses; the
node's own ``keep_out_boxes`` and ``table_margin`` stand until the planner answers (or always,
with ``planner_node`` empty).
"""

from typing import Optional, Sequence

from geometry_msgs.msg import Point, PoseArray, PoseStamped
from mover6_control.collision.geometry import keep_out_boxes, KeepOutBox
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk_batch
from mover6_control.nodes.messages.conversions import pose_from_msg
from mover6_control.nodes.messages.demand_messages import demands_from_msg
from mover6_control.nodes.runtime import shutdown
from mover6_control.nodes.runtime.callback_guard import CallbackGuard
from mover6_control.nodes.runtime.params import declare
from mover6_control.nodes.runtime.qos import LATCHED_QOS
from mover6_control.parameters import MARKERS
from mover6_control.validation import as_finite_array
import numpy as np
from rcl_interfaces.msg import ParameterEvent, ParameterValue
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.parameter import parameter_value_to_python
from rclpy.task import Future
from std_msgs.msg import ColorRGBA, Float32MultiArray
from visualization_msgs.msg import Marker, MarkerArray

FOLLOWED = ('keep_out_boxes', 'table_margin')
AXIS_LENGTH = 0.06      # [m] of the goal's axes
MAX_POSES = 101         # a path goal's poses shown at most (the planner's 100 vias and the goal)
COLOURS = {'table': (0.6, 0.5, 0.4, 1.0), 'margin': (0.9, 0.8, 0.2, 0.15),
           'keep_out': (0.9, 0.1, 0.1, 0.35), 'path': (0.1, 0.6, 1.0, 1.0),
           'via': (1.0, 0.6, 0.0, 1.0)}
AXIS_COLOURS = ((1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0))


def colour(rgba: Sequence[float]) -> ColorRGBA:
    """Return a ``ColorRGBA``."""
    return ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))


def point(p: Sequence[float]) -> Point:
    """Return a ``geometry_msgs/Point`` of three numbers."""
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def box_marker(ns: str, mid: int, lower: Sequence[float], upper: Sequence[float],
               rgba: Sequence[float]) -> Marker:
    """Return a CUBE marker spanning ``lower`` .. ``upper`` [m] (axis-aligned)."""
    m = Marker(ns=ns, id=mid, type=Marker.CUBE, action=Marker.ADD, color=colour(rgba))
    m.pose.position = point([(lo + hi) / 2.0 for lo, hi in zip(lower, upper)])
    m.pose.orientation.w = 1.0
    m.scale.x, m.scale.y, m.scale.z = (float(hi - lo) for lo, hi in zip(lower, upper))
    return m


def scene_markers(table_size: float, table_margin: float,
                  boxes: Sequence[KeepOutBox]) -> list[Marker]:
    """Return the table (slab and margin) and keep-out markers."""
    half = table_size / 2.0
    out = [box_marker('table', 0, (-half, -half, -0.01), (half, half, 0.0), COLOURS['table'])]
    if table_margin > 0.0:
        out.append(box_marker('table', 1, (-half, -half, 0.0), (half, half, table_margin),
                              COLOURS['margin']))
    out += [box_marker('keep_out', k, b.lower, b.upper, COLOURS['keep_out'])
            for k, b in enumerate(boxes)]
    return out


def goal_markers(T_goal: np.ndarray, vias: Sequence[np.ndarray] = ()) -> list[Marker]:
    """Return the goal's axes (three arrows along its x, y, z) and its via poses (spheres)."""
    out = []
    for k in range(3):
        m = Marker(ns='goal', id=k, type=Marker.ARROW, action=Marker.ADD,
                   color=colour(AXIS_COLOURS[k]))
        m.pose.orientation.w = 1.0
        m.points = [point(T_goal[:3, 3]), point(T_goal[:3, 3] + AXIS_LENGTH * T_goal[:3, k])]
        m.scale.x, m.scale.y, m.scale.z = 0.006, 0.012, 0.015   # shaft, head width, head length
        out.append(m)
    m = Marker(ns='goal', id=3, type=Marker.SPHERE_LIST, action=Marker.ADD,
               color=colour(COLOURS['via']))
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = 0.015
    m.points = [point(T[:3, 3]) for T in vias]
    out.append(m)
    return out


def path_marker(positions: np.ndarray) -> Marker:
    """Return the tool path through ``positions`` (n, 3) [m] as a line strip."""
    m = Marker(ns='planned_path', id=0, type=Marker.LINE_STRIP, action=Marker.ADD,
               color=colour(COLOURS['path']))
    m.pose.orientation.w = 1.0
    m.scale.x = 0.004
    m.points = [point(p) for p in positions]
    return m


def followed_value(value: ParameterValue) -> object:
    """Return a ``ParameterValue`` as Python; raise ``InvalidInputError`` on an unknown type."""
    try:
        return parameter_value_to_python(value)
    except RuntimeError as err:         # rclpy's error for a type it does not know
        raise InvalidInputError(f'parameter event: {err}') from None


class MarkersNode(Node):
    """Publish the planner's world and motions as markers; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('markers', **kwargs)
        self.guard = CallbackGuard(self)     # no callback ends the node (a bad goal is refused)
        declare(self, MARKERS, check_config=lambda get: keep_out_boxes(get('keep_out_boxes')),
                guard=self.guard)
        p = {name: self.get_parameter(name).value for name in MARKERS}
        self.frame = p['frame_prefix'] + p['frame_id']
        self.table_size = p['table_size']
        self.arm = mover6()      # forward kinematics only: the limits do not matter
        self.followed = {'keep_out_boxes': list(p['keep_out_boxes']),
                         'table_margin': p['table_margin']}
        self.goal = []
        self.path = []
        self.pub = self.create_publisher(MarkerArray, 'markers', LATCHED_QOS)
        self.guard.subscription(PoseStamped, 'pose_goal', self.on_pose_goal, 10)
        self.guard.subscription(PoseArray, 'path_goal', self.on_path_goal, 10)
        self.guard.subscription(Float32MultiArray, 'joint_demands', self.on_demands, 10)
        self.planner = p['planner_node']
        self.planner_answered = False
        if self.planner:
            self.client = self.create_client(GetParameters, f'{self.planner}/get_parameters')
            self.guard.subscription(ParameterEvent, '/parameter_events', self.on_event, 10)
            self.ask_timer = self.guard.timer(1.0, self.ask_planner)
        self.publish()

    def ask_planner(self) -> None:
        """Ask the planner for its table margin and keep-out boxes (until it answers)."""
        if self.planner_answered:
            self.ask_timer.cancel()
            return
        if not self.client.service_is_ready():
            return
        future = self.client.call_async(GetParameters.Request(names=list(FOLLOWED)))
        future.add_done_callback(self.guard.wrap('planner answer', self.on_planner_answer))

    def on_planner_answer(self, future: Future) -> None:
        """Take the planner's values and publish."""
        result = future.result()
        if result is None or len(result.values) != len(FOLLOWED):
            return
        self.planner_answered = True
        self.follow({n: followed_value(v) for n, v in zip(FOLLOWED, result.values)})

    def on_event(self, msg: ParameterEvent) -> None:
        """Follow a change of the planner's table margin or keep-out boxes."""
        if msg.node.lstrip('/') != self.planner_full_name():
            return
        changed = {p.name: followed_value(p.value)
                   for p in list(msg.new_parameters) + list(msg.changed_parameters)
                   if p.name in FOLLOWED}
        if changed:
            self.follow(changed)

    def planner_full_name(self) -> str:
        """Return the planner's node name with this node's namespace (no leading slash)."""
        if self.planner.startswith('/'):
            return self.planner.lstrip('/')
        ns = self.get_namespace().strip('/')
        return f'{ns}/{self.planner}' if ns else self.planner

    def follow(self, values: dict[str, object]) -> None:
        """
        Take the planner's ``values`` (names in ``FOLLOWED``) and publish.

        Checked whole first (keep-out boxes, a finite margin): a malformed value changes nothing.
        """
        new = dict(self.followed)
        for name, value in values.items():
            if name == 'keep_out_boxes':
                boxes = as_finite_array(value, (None,), name)
                keep_out_boxes(boxes)            # raises on a malformed list
                new[name] = boxes.tolist()
            else:
                new[name] = as_finite_array(value, (), name).item()
        self.followed = new
        self.publish()

    def on_pose_goal(self, msg: PoseStamped) -> None:
        """Show a pose goal; the path of the goal before is cleared (a malformed pose: refused)."""
        self.goal = goal_markers(pose_from_msg(msg.pose).matrix)
        self.path = []
        self.publish()

    def on_path_goal(self, msg: PoseArray) -> None:
        """Show a path goal: its last pose is the goal, the others its via poses."""
        if not msg.poses:
            return
        if len(msg.poses) > MAX_POSES:
            raise InvalidInputError(f'a path goal has at most {MAX_POSES} poses to show, got '
                                    f'{len(msg.poses)}')
        poses = [pose_from_msg(p).matrix for p in msg.poses]
        self.goal = goal_markers(poses[-1], poses[:-1])
        self.path = []
        self.publish()

    def on_demands(self, msg: Float32MultiArray) -> None:
        """Show the tool path of the demanded waypoints; malformed ones are refused (guard)."""
        Q = demands_from_msg(msg, self.arm.n_joints)     # the controller refuses them too
        self.path = [path_marker(fk_batch(self.arm, Q)[:, :3, 3])]
        self.publish()

    def markers(self) -> MarkerArray:
        """Return the whole ``MarkerArray`` (a DELETEALL first: no stale marker stays)."""
        try:
            boxes = keep_out_boxes(self.followed['keep_out_boxes'])
        except InvalidInputError:
            boxes = ()
        items = [Marker(action=Marker.DELETEALL)]
        items += scene_markers(self.table_size, self.followed['table_margin'], boxes)
        items += self.goal + self.path
        stamp = self.get_clock().now().to_msg()
        for m in items:
            m.header.frame_id = self.frame
            m.header.stamp = stamp
            m.frame_locked = True
        return MarkerArray(markers=items)

    def publish(self) -> None:
        """Publish the markers."""
        self.pub.publish(self.markers())


def main(args: Optional[list[str]] = None) -> None:
    """Run the markers node until Ctrl-C."""
    try:
        shutdown.run_node(MarkersNode, args)
    except InvalidInputError as err:
        raise SystemExit(f'markers: {err}')


if __name__ == '__main__':
    main()
