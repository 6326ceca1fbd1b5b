"""
The console's scene of the arm: the arm from the URDF, the planned tool path, the ghost arm.

The package's URDF is kinematics only (no geometry): each link is given the collision
checker's capsule of that body as its visual (``arm_urdf``), so the arm drawn is the arm the
checker collides.
"""

from pathlib import Path
from typing import Optional

from mover6_control.collision.geometry import CollisionGeometry
from mover6_control.nodes.console.collision_scene import capsule_pose
import numpy as np
from viser import ViserServer
from viser.extras import ViserUrdf
import yourdfpy

ARM_COLOUR = (0.55, 0.6, 0.68, 1.0)
GHOST_COLOUR = (0.9, 0.2, 0.2, 0.45)     # the closest reachable pose of a refused goal
PREVIEW_COLOUR = (40, 120, 255)         # the path of "Plan" (made in the console)
DEMAND_COLOUR = (20, 170, 60)           # the path of the planner's /joint_demands
PATH_WIDTH = 0.004                      # [m]


def arm_urdf(urdf_path: Path, geometry: CollisionGeometry,
             rgba: tuple = ARM_COLOUR) -> yourdfpy.URDF:
    """Return the URDF of ``urdf_path`` with each link's capsule of ``geometry`` as visual."""
    robot = yourdfpy.URDF.load(str(urdf_path)).robot
    links = {link.name: link for link in robot.links}
    material = yourdfpy.Material(name='arm', color=yourdfpy.Color(rgba=np.array(rgba)))
    for capsule in geometry.capsules:
        link = links[geometry.body_names[capsule.body]
                     if capsule.body else robot.links[0].name]
        length, T = capsule_pose(capsule)
        shapes = [(T, yourdfpy.Geometry(cylinder=yourdfpy.Cylinder(capsule.radius, length)))]
        for end in (capsule.p0, capsule.p1):
            T_end = np.eye(4)
            T_end[:3, 3] = end
            shapes.append((T_end, yourdfpy.Geometry(sphere=yourdfpy.Sphere(capsule.radius))))
        link.visuals += [yourdfpy.Visual(name=f'{capsule.name} {k}', origin=origin,
                                         geometry=shape, material=material)
                         for k, (origin, shape) in enumerate(shapes)]
    return yourdfpy.URDF(robot=robot, build_scene_graph=True, load_meshes=True)


class StateView:
    """The arm of ``urdf_path`` in the scene, moved by ``show_joints``; paths and a ghost arm."""

    def __init__(self, server: ViserServer, urdf_path: Path, joint_names: tuple,
                 geometry: CollisionGeometry):
        """Load the URDF twice (the arm and its ghost); ``joint_names`` orders the joints."""
        urdf = arm_urdf(urdf_path, geometry)
        order = list(urdf.actuated_joint_names)
        # URDF order <- ours; a joint outside the arm (the gripper) stays at 0 (the extra slot).
        names = list(joint_names)
        self.index = [names.index(name) if name in names else len(names) for name in order]
        self.server = server
        self.arm = ViserUrdf(server, urdf, root_node_name='/arm')
        self.ghost = ViserUrdf(server, arm_urdf(urdf_path, geometry, GHOST_COLOUR),
                               root_node_name='/ghost')
        self._ghost_visible(False)
        self.paths = {}
        self.q = None

    def show_joints(self, q: np.ndarray) -> None:
        """Move the arm to the joint positions ``q`` (6,) [rad], in the package's joint order."""
        self.q = np.asarray(q, dtype=float)
        self.arm.update_cfg(self._cfg(self.q))

    def show_ghost(self, q: Optional[np.ndarray]) -> None:
        """Show the ghost arm at ``q`` (6,) [rad]; None hides it."""
        if q is not None:
            self.ghost.update_cfg(self._cfg(np.asarray(q, dtype=float)))
        self._ghost_visible(q is not None)

    def _cfg(self, q: np.ndarray) -> np.ndarray:
        """Return the URDF's configuration of the arm's ``q`` (the gripper at 0)."""
        return np.append(q, 0.0)[self.index]

    def _ghost_visible(self, visible: bool) -> None:
        self.ghost.show_visual = visible

    def show_path(self, kind: str, points: Optional[np.ndarray]) -> None:
        """Show the tool path ``points`` (n, 3) [m] of ``kind`` (preview, demand); None hides."""
        old = self.paths.pop(kind, None)
        if old is not None:
            old.remove()
        if points is None or len(points) < 2:
            return
        colour = PREVIEW_COLOUR if kind == 'preview' else DEMAND_COLOUR
        self.paths[kind] = self.server.scene.add_spline_catmull_rom(
            f'/path/{kind}', points=np.asarray(points, dtype=float), curve_type='chordal',
            thickness=PATH_WIDTH, color=colour)
