"""The console's scene of what the collision checker sees: table, margin, keep-out, the tool."""

from mover6_control.collision.checker import CollisionSettings
from mover6_control.collision.geometry import build_geometry, Capsule
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk_frames
from mover6_control.kinematics.rotations import matrix_to_quaternion
import numpy as np
import trimesh
from viser import ViserServer

TABLE_SIZE = 1.0             # [m] across, as the markers node draws it
SCENE_COLOURS = {'table': (150, 125, 100), 'margin': (230, 205, 50),
                 'keep_out': (230, 25, 25), 'tool': (255, 150, 0)}


def wxyz(R: np.ndarray) -> np.ndarray:
    """Return the quaternion (w, x, y, z) of rotation ``R`` (viser's order)."""
    x, y, z, w = matrix_to_quaternion(R)
    return np.array([w, x, y, z])


def capsule_pose(capsule: Capsule) -> tuple[float, np.ndarray]:
    """Return a capsule's segment length [m] and the pose (4, 4) of its centre, z along it."""
    p0, p1 = np.asarray(capsule.p0, dtype=float), np.asarray(capsule.p1, dtype=float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 0.0 else np.array([0.0, 0.0, 1.0])
    x = np.cross([0.0, 1.0, 0.0], z) if abs(z[1]) < 0.9 else np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = 0.5 * (p0 + p1)
    return length, T


def capsule_mesh(capsule: Capsule) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Return a capsule's mesh along z, centred, and its pose (4, 4) in its body's frame."""
    length, T = capsule_pose(capsule)
    return trimesh.creation.capsule(height=length, radius=capsule.radius, count=[12, 12]), T


class CollisionScene:
    """The table, its margin, the keep-out boxes and the tool as ``settings`` make them."""

    def __init__(self, server: ViserServer, arm: ArmModel):
        """Draw nothing yet: ``show`` draws the settings in force."""
        self.server = server
        self.arm = arm
        self.geometry = None
        self.handles = []
        self.tool = None             # (handle, pose in the flange body's frame) or None
        self.settings = None

    def show(self, settings: CollisionSettings) -> None:
        """Draw (again) what ``settings`` make the checker collide."""
        if settings == self.settings:
            return
        self.settings = settings
        for handle in self.handles:
            handle.remove()
        self.handles = []
        self.geometry = geometry = build_geometry(self.arm, settings.tool,
                                                  settings.table_margin, settings.keep_out)
        half = TABLE_SIZE / 2.0
        self.handles.append(self.server.scene.add_box(
            '/collision/table', color=SCENE_COLOURS['table'],
            dimensions=(TABLE_SIZE, TABLE_SIZE, 0.01),
            position=(0.0, 0.0, -0.005)))
        if geometry.table_margin > 0.0:
            self.handles.append(self.server.scene.add_box(
                '/collision/table_margin', color=SCENE_COLOURS['margin'], opacity=0.15,
                dimensions=(2 * half, 2 * half, geometry.table_margin),
                position=(0.0, 0.0, geometry.table_margin / 2.0)))
        for k, box in enumerate(geometry.keep_out):
            lower, upper = np.asarray(box.lower), np.asarray(box.upper)
            self.handles.append(self.server.scene.add_box(
                f'/collision/keep_out_{k}', color=SCENE_COLOURS['keep_out'], opacity=0.35,
                dimensions=tuple(upper - lower), position=tuple((lower + upper) / 2.0)))
        self.tool = None
        if isinstance(geometry.tool, Capsule):
            mesh, T = capsule_mesh(geometry.tool)
            mesh.visual.face_colors = (*SCENE_COLOURS['tool'], 110)
            handle = self.server.scene.add_mesh_trimesh('/collision/tool', mesh)
            self.handles.append(handle)
            self.tool = (handle, T, geometry.tool.body)

    def follow(self, q: np.ndarray) -> None:
        """Put the tool where the flange is at joint positions ``q`` (6,) [rad]."""
        if self.tool is None:
            return
        handle, T_body, body = self.tool
        T = fk_frames(self.arm, q)[body - 1] @ T_body      # body i: the frame of joint i
        handle.position = T[:3, 3]
        handle.wxyz = wxyz(T[:3, :3])
