"""
The Mover6's collision shapes, derived from its maker's meshes: the fit behind ``body_model``.

Each link's mesh (``meshes/Joint0.stl`` = ``base_link`` .. ``Joint6.stl`` = ``link6``, in
metres, in the link's frame) is cut into slabs across one axis of the link's frame
(``BODY_SLABS``); each slab's part of the surface gets one shape along the housing's own axis:
a capsule (a segment and a radius) for the moving links, a flat-ended cylinder where the part is
a flat disc or column (the base, the flange). A slab may instead be declared carried by the base
('base'): a part turning about joint 1 inside the base's column, checked to be inside the base's
shapes at every angle.

The cut is exact: every triangle is clipped at the slab planes (the edges' crossings added), so
each slab's part of the surface is the convex hull of points in the slab, and a convex shape
that contains those points contains that part of the surface, not only its vertices. Each
shape is the smallest by volume over a grid of segment ends, centred on the smallest circle
around the points seen along its axis; its radius (and a cylinder's ends) grows by ``MARGIN``,
so every point of the surface is at least ``MARGIN`` inside the model.

Refused, with the file and the reason (``MeshError``): a mesh that is missing, unreadable or
empty, or not in its link's frame (its bounds more than ``FRAME_TOLERANCE`` from the joint
origins it should hold, or larger than ``MAX_EXTENT``: a mesh in millimetres, or another
link's). ROS-free; trimesh reads the files.
"""

from __future__ import annotations

from dataclasses import dataclass
import os

from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
import numpy as np

MARGIN = 0.001             # [m] every point of the surface at least this far inside the model
FRAME_TOLERANCE = 0.02     # [m] a joint origin at most this far outside its link's mesh bounds
MAX_EXTENT = 0.5           # [m] no Mover6 part reaches further than this from its frame
MESH_FILES = tuple(f'Joint{i}.stl' for i in range(7))     # base_link, link1 .. link6
AXES = {'x': 0, 'y': 1, 'z': 2}

# Per body (0: base_link, i: link i): the axis its slabs are cut across, and the slabs, each
# (upper bound [m] along that axis, the shape, its axis, the part's name: the shape is named
# '<link> <part>'); the last slab is unbounded above.
# The axes are the housings' own: the shoulder and elbow along the joint-2 and joint-3 axes
# (y), the upper arm's side plate and the forearm along the arm (z of link2, link4), the
# forearm's root beside the elbow along link3's z, the wrist fork along joint 5's axis.
BODY_SLABS = {
    0: ('z', ((0.011, 'cylinder', 'z', 'plate'),       # the base plate on the table
              (None, 'cylinder', 'z', 'column'))),     # the column up to joint 1
    1: ('z', ((0.002, 'base', 'z', 'shaft'),           # the shaft inside the base's column
              (0.02, 'cylinder', 'z', 'turntable'),    # the turntable on top of the column
              (None, 'either', 'y', 'shoulder'))),     # the shoulder housing along joint 2
    2: ('z', ((0.045, 'either', 'y', 'shoulder'),      # the shoulder end, along joint 2
              (0.15, 'either', 'z', 'plate'),          # the side plate, +y of the axis
              (None, 'either', 'y', 'elbow'))),        # the elbow end, along joint 3
    3: ('x', ((-0.05, 'either', 'z', 'rear'),          # the housing's rear, behind joint 4
              (None, 'either', 'y', 'elbow'))),        # the elbow housing, along joint 3
    4: ('z', ((0.235, 'either', 'z', 'forearm'),       # the forearm tube
              (None, 'either', 'y', 'fork'))),         # the wrist fork, along joint 5
    5: ('z', ((0.005, 'either', 'y', 'pivot'),         # the wrist pivot, along joint 5
              (None, 'either', 'y', 'wrist'))),        # the L-shaped wrist body
    6: ('z', ((None, 'cylinder', 'z', 'flange'),)),    # the flange disc
}


class MeshError(InvalidInputError):
    """A mesh the derivation cannot use: ``path`` and the reason in the message."""

    def __init__(self, path: str, reason: str):
        """Keep the file and say why it is refused."""
        super().__init__(f'{path}: {reason}')
        self.path = path


@dataclass(frozen=True)
class FittedShape:
    """A derived shape: ``kind`` 'capsule' or 'cylinder', on ``body``, segment p0-p1 [m]."""

    name: str
    body: int
    kind: str
    p0: tuple
    p1: tuple
    radius: float


def load_vertices(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Return the vertices (n, 3) [m] and triangles (m, 3) of the mesh file ``path``."""
    import trimesh   # local import: only the derivation reads meshes

    if not os.path.isfile(path):
        raise MeshError(path, 'missing (no such file)')
    try:
        mesh = trimesh.load(path, force='mesh', process=True)
    except Exception as err:  # noqa: B902 - any reader failure is an unreadable file
        raise MeshError(path, f'unreadable: {type(err).__name__}: {err}') from None
    vertices = np.asarray(getattr(mesh, 'vertices', np.zeros((0, 3))), dtype=float)
    faces = np.asarray(getattr(mesh, 'faces', np.zeros((0, 3))), dtype=int)
    if len(vertices) < 4 or len(faces) == 0:
        raise MeshError(path, 'unreadable: no triangles in it')
    if not np.all(np.isfinite(vertices)):
        raise MeshError(path, 'unreadable: vertices that are not finite numbers')
    return vertices, faces


def frame_points(arm: ArmModel, body: int) -> np.ndarray:
    """Return the joint origins (k, 3) [m] the mesh of ``body`` holds, in that body's frame."""
    if body == 0:
        return np.array([[0.0, 0.0, 0.0], arm.origins[0][:3, 3]])
    nxt = arm.origins[body][:3, 3] if body < arm.n_joints else arm.tool[:3, 3]
    return np.array([[0.0, 0.0, 0.0], nxt])


def check_frame(path: str, vertices: np.ndarray, origins: np.ndarray) -> None:
    """Refuse a mesh whose bounds are not about its link's joint ``origins`` (k, 3) [m]."""
    lower, upper = vertices.min(axis=0), vertices.max(axis=0)
    extent = float(np.max(np.abs(np.concatenate([lower, upper]))))
    if extent > MAX_EXTENT:
        raise MeshError(path, f"not in its link's frame: it reaches"
                              f' {extent:.3f} m from the '
                              f'frame (more than {MAX_EXTENT} m; a mesh in millimetres?)')
    for p in origins:
        outside = float(np.linalg.norm(np.maximum(lower - p, 0.0) + np.maximum(p - upper, 0.0)))
        if outside > FRAME_TOLERANCE:
            raise MeshError(path, f"not in its link's frame: the joint origin "
                                  f'{np.round(p, 4).tolist()} m is {outside * 1e3:.1f} mm '
                                  f'outside its bounds {np.round(lower, 4).tolist()} .. '
                                  f'{np.round(upper, 4).tolist()} m')


def slab_points(vertices: np.ndarray, faces: np.ndarray, axis: int, cuts: list) -> list:
    """
    Return the surface's points in each slab between ``cuts`` along ``axis`` (a list of arrays).

    The points are the vertices and every crossing of a triangle edge with a cut, so that the
    part of each triangle in a slab is the convex hull of that slab's points.
    """
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]],
                                              faces[:, [2, 0]]]), axis=1), axis=0)
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    points = [vertices]
    for c in cuts:
        da, db = a[:, axis] - c, b[:, axis] - c
        cross = (da * db) < 0.0
        t = da[cross] / (da[cross] - db[cross])
        p = a[cross] + t[:, None] * (b[cross] - a[cross])
        p[:, axis] = c
        points.append(p)
    P = np.concatenate(points)
    bounds = [-np.inf] + list(cuts) + [np.inf]
    eps = 1e-9
    return [P[(P[:, axis] >= lo - eps) & (P[:, axis] <= hi + eps)]
            for lo, hi in zip(bounds[:-1], bounds[1:])]


def enclosing_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Return the centre (2,) and radius of the smallest circle around ``points`` (n, 2)."""
    P = np.unique(np.round(points, 9), axis=0)
    rng = np.random.default_rng(0)
    P = P[rng.permutation(len(P))]

    def circle2(a, b):
        c = 0.5 * (a + b)
        return c, float(np.linalg.norm(a - c))

    def circle3(a, b, c):
        d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
        if abs(d) < 1e-15:
            pairs = [circle2(a, b), circle2(a, c), circle2(b, c)]
            return max(pairs, key=lambda cr: cr[1])
        sa, sb, sc = a @ a, b @ b, c @ c
        ux = (sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1])) / d
        uy = (sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])) / d
        centre = np.array([ux, uy])
        return centre, float(np.linalg.norm(a - centre))

    def inside(cr, p):
        return np.linalg.norm(p - cr[0]) <= cr[1] + 1e-12

    cr = (P[0], 0.0)
    for i in range(1, len(P)):
        if inside(cr, P[i]):
            continue
        cr = (P[i], 0.0)
        for j in range(i):
            if inside(cr, P[j]):
                continue
            cr = circle2(P[i], P[j])
            for k in range(j):
                if not inside(cr, P[k]):
                    cr = circle3(P[i], P[j], P[k])
    return np.asarray(cr[0], dtype=float), float(cr[1])


def _basis(axis: int) -> np.ndarray:
    """Return the unit axis and two unit vectors across it (3, 3), rows."""
    eye = np.eye(3)
    return np.array([eye[axis], eye[(axis + 1) % 3], eye[(axis + 2) % 3]])


def segment_distance(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Return the distance (n,) of ``points`` (n, 3) from the segment ``p0``-``p1``."""
    d = p1 - p0
    length2 = float(d @ d)
    t = np.zeros(len(points)) if length2 == 0.0 else np.clip((points - p0) @ d / length2, 0, 1)
    return np.linalg.norm(points - (p0 + t[:, None] * d), axis=1)


def fit_shape(points: np.ndarray, kind: str, axis: int, margin: float = MARGIN) -> tuple:
    """
    Return (p0, p1, radius) of the smallest ``kind`` along ``axis`` around ``points`` (n, 3).

    A cylinder is exact: the circle around the points seen along its axis, its ends at their
    extremes, all grown by ``margin``. A capsule's segment runs through that circle's centre;
    its ends are chosen on a grid between the extremes for the least volume.
    """
    B = _basis(axis)
    local = points @ B.T                    # (t, u, w)
    centre, rc = enclosing_circle(local[:, 1:])
    t = local[:, 0]
    lo, hi = float(t.min()), float(t.max())

    def world(t_value):
        return B.T @ np.array([t_value, centre[0], centre[1]])

    if kind == 'cylinder':
        return world(lo - margin), world(hi + margin), rc + margin
    best = None
    shrink = np.linspace(0.0, max(rc, 1e-6), 41)
    for s0 in shrink:
        for s1 in shrink:
            a, b = lo + s0, hi - s1
            if b < a:
                a = b = 0.5 * (lo + s0 + hi - s1)
            p0, p1 = world(a), world(b)
            r = float(segment_distance(points, p0, p1).max())
            volume = np.pi * r * r * (b - a) + 4.0 / 3.0 * np.pi * r ** 3
            if best is None or volume < best[0]:
                best = (volume, p0, p1, r)
    _, p0, p1, r = best
    return p0, p1, r + margin


def shape_volume(kind: str, p0, p1, radius: float) -> float:
    """Return the volume [m^3] of a capsule or cylinder."""
    length = float(np.linalg.norm(np.asarray(p1) - np.asarray(p0)))
    cap = 4.0 / 3.0 * np.pi * radius ** 3 if kind == 'capsule' else 0.0
    return np.pi * radius * radius * length + cap


def smallest_shape(points: np.ndarray, kind: str, axis: int, margin: float) -> tuple:
    """Return (kind, (p0, p1, radius)) of ``fit_shape``; kind 'either': the smaller of both."""
    kinds = ('capsule', 'cylinder') if kind == 'either' else (kind,)
    fits = [(k, fit_shape(points, k, axis, margin)) for k in kinds]
    return min(fits, key=lambda kf: shape_volume(kf[0], *kf[1]))


def signed_distance(kind: str, p0, p1, radius: float, points: np.ndarray) -> np.ndarray:
    """Return how far (n,) [m] ``points`` (n, 3) are outside a capsule or cylinder (< 0: in)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    if kind == 'capsule':
        return segment_distance(points, p0, p1) - radius
    d = p1 - p0
    length = float(np.linalg.norm(d))
    t = (points - p0) @ d / length                       # along the axis, from p0
    radial = np.linalg.norm(points - p0 - np.outer(t / length, d), axis=1) - radius
    axial = np.maximum(-t, t - length)
    outside = np.hypot(np.maximum(radial, 0.0), np.maximum(axial, 0.0))
    return np.where((radial > 0.0) | (axial > 0.0), outside, np.maximum(radial, axial))


def derive_body(arm: ArmModel, mesh_dir: str, slabs: dict = BODY_SLABS,
                margin: float = MARGIN) -> tuple:
    """
    Return the ``FittedShape``s of every body of ``arm`` from the meshes in ``mesh_dir``.

    Raises ``MeshError`` (the file and the reason) for a mesh that is missing, unreadable or
    not in its link's frame, and for a part declared carried by the base that leaves it.
    """
    names = ['base'] + [j.replace('joint', 'link') for j in arm.joint_names]
    shapes, carried = [], []
    for body in sorted(slabs):
        path = os.path.join(mesh_dir, MESH_FILES[body])
        vertices, faces = load_vertices(path)
        check_frame(path, vertices, frame_points(arm, body))
        axis_name, rows = slabs[body]
        axis = AXES[axis_name]
        cuts = [row[0] for row in rows[:-1]]
        parts = slab_points(vertices, faces, axis, cuts)
        for (_, kind, along, part), P in zip(rows, parts):
            if len(P) == 0:
                continue
            if kind == 'base':
                carried.append((body, path, P))
                continue
            kind, (p0, p1, r) = smallest_shape(P, kind, AXES[along], margin)
            shapes.append(FittedShape(f'{names[body]} {part}', body, kind,
                                      tuple(float(v) for v in p0),
                                      tuple(float(v) for v in p1), float(r)))
    for body, path, P in carried:
        check_carried(arm, body, path, P, [s for s in shapes if s.body == 0], margin)
    # The fit's own check: every vertex inside by the margin.
    for body, worst in largest_outside(mesh_dir, shapes, slabs).items():
        if worst > -margin + 1e-7:
            raise MeshError(MESH_FILES[body], f'the fit leaves a vertex {worst * 1e3:.2f} '
                                              f'mm from its surface (less than {margin} m in)')
    return tuple(shapes)


def largest_outside(mesh_dir: str, shapes, slabs: dict = BODY_SLABS) -> dict:
    """
    Return {body: the largest distance [m] of its mesh's vertices outside its shapes} (< 0: in).

    A part carried by the base (link1's shaft) is left out: it is inside the base's shapes.
    """
    out = {}
    for body in sorted(slabs):
        vertices, _ = load_vertices(os.path.join(mesh_dir, MESH_FILES[body]))
        first = slabs[body][1][0]
        if first[1] == 'base':
            vertices = vertices[vertices[:, AXES[slabs[body][0]]] >= first[0]]
        out[body] = float(np.min([signed_distance(s.kind, s.p0, s.p1, s.radius, vertices)
                                  for s in shapes if s.body == body], axis=0).max())
    return out


def min_table_margin(outside: dict) -> float:
    """
    Return the smallest table margin [m] the body needs, from ``largest_outside``'s figures.

    The checker keeps every shape of the moving links at least the margin above the table; a
    vertex is at most its link's largest outside distance below its shapes, so a margin of the
    largest of them over links 1 to 6 (0 when every vertex is inside) keeps every vertex of the
    real arm above the table. Rounded up to 0.1 mm.
    """
    worst = max(v for body, v in outside.items() if body > 0)
    return float(np.ceil(max(worst, 0.0) * 1e4) / 1e4)


def check_carried(arm: ArmModel, body: int, path: str, points: np.ndarray, base: list,
                  margin: float) -> None:
    """Refuse a part of link 1 said to turn inside the base that leaves the base's cylinders."""
    if body != 1 or not base:
        raise MeshError(path, 'only a part of link1 can be carried by the base')
    T = arm.origins[0]
    world = points @ T[:3, :3].T + T[:3, 3]      # in base_link, at joint 1 = 0
    radius = np.hypot(world[:, 0], world[:, 1])  # turning about the base's z axis
    ok = np.zeros(len(points), dtype=bool)
    for shape in base:
        if shape.kind != 'cylinder' or abs(shape.p0[0] - shape.p1[0]) + abs(
                shape.p0[1] - shape.p1[1]) > 1e-9:
            continue                             # only an upright cylinder holds a turning part
        off = float(np.hypot(shape.p0[0], shape.p0[1]))     # its axis from joint 1's
        z0, z1 = sorted((shape.p0[2], shape.p1[2]))
        ok |= ((radius + off <= shape.radius - margin) & (world[:, 2] >= z0 + margin)
               & (world[:, 2] <= z1 - margin))
    if not np.all(ok):
        worst = world[~ok][0]
        raise MeshError(path, f"its part said to turn inside the base leaves the base's "
                              f'cylinders (a point at {np.round(worst, 4).tolist()} m)')
