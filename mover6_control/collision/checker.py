"""
The collision checker: whether a joint path (N x 6) sweeps the arm into anything.

Into the table, into itself or into a keep-out zone.

``CollisionChecker.check_path`` samples the motion densely between the waypoints (straight in
joint space, no joint moving more than ``max_joint_step`` between samples), and returns a
``PathCheck``: the first colliding sample with the two shapes and how deep, and the smallest
clearance of each kind (table, self, keep-out) along the whole path. ``check_configurations``
does the same for given samples only. ROS-free, clock-free.

Shapes and rules are ``geometry.CollisionGeometry``'s (the simulator's geoms): link capsules,
a tool capsule or box, the table plane (a shape closer than ``table_margin`` to it collides),
self-collision between links two or more apart, axis-aligned keep-out boxes.

How, and why so (measured, ``bench/bench_collision.py`` and the figures below, on this
machine's shared cores): MuJoCo's own collision pipeline on the model ``geometry.collision_mjcf``
builds from the same shapes as the simulator's, one reused ``MjData``, per sample
``mj_kinematics`` + ``mj_collision`` (a bounding-box broad phase, then exact capsule, box and
plane narrow phases), about 3.5 us per sample unloaded; ``bench_collision`` on a loaded machine:
1.2 ms median, 1.4 ms p95 for a planned 100-waypoint path (157 samples), 8 ms for 1000
waypoints (1057 samples). Every geom reports contacts up to ``HORIZON`` apart (the table's up
to its margin further), so the clearances below that are exact and only close pairs cost
anything.
Measured against it: vectorised closed-form capsule distances in numpy over all samples at once
(one ``fk_frames_batch``, then one segment-to-segment distance per pair) took 4.8 ms for 300
samples without keep-out boxes and 35 ms with one (a golden-section search of the box's signed
distance along each capsule), so the loop over samples in C wins here; ``mujoco.rollout`` steps
the dynamics and cannot pose the arm at given samples. Agreement with the analytic distances was
checked on 300 random configurations (same colliding set).
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.collision.geometry import (build_geometry, collision_mjcf,
                                               CollisionGeometry, keep_out_boxes, TABLE,
                                               ToolVolume)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.parameters import PLANNER   # the defaults
import mujoco
import numpy as np

# [m] contacts closer than this are reported, so a clearance below it is known exactly.
HORIZON = 0.05
KINDS = {0: 'self', 1: 'keep_out', 2: 'table'}
# [m] how much deeper a contact the arm starts in may get along an escaping path.
ESCAPE_TOLERANCE = 1e-4


@dataclass(frozen=True)
class CollisionSettings:
    """
    What the checker checks; defaults are the planner node's parameter defaults.

    ``enabled`` False checks nothing. ``tool`` the tool volume, ``table_margin`` [m] the
    clearance kept above the table, ``keep_out`` the flat list of boxes (6 values each: x, y, z
    min then max [m] in base_link; boxes without volume are none), ``max_joint_step`` [rad]
    the largest joint step between two checked samples.
    """

    enabled: bool = PLANNER['collision_check'].default
    tool: ToolVolume = ToolVolume()
    table_margin: float = PLANNER['table_margin'].default
    keep_out: tuple = PLANNER['keep_out_boxes'].default
    max_joint_step: float = PLANNER['collision_step'].default

    def __post_init__(self):
        """Reject settings the checker cannot use."""
        if not np.isfinite(self.max_joint_step) or self.max_joint_step <= 0.0:
            raise InvalidInputError(f'collision max_joint_step must be > 0, got '
                                    f'{self.max_joint_step}')
        if not np.isfinite(self.table_margin) or self.table_margin < 0.0:
            raise InvalidInputError(f'table_margin must be >= 0, got {self.table_margin}')
        keep_out_boxes(self.keep_out)        # raises: not 6 values per box, max below min
        object.__setattr__(self, 'keep_out', tuple(float(v) for v in self.keep_out))


@dataclass(frozen=True)
class Contact:
    """
    The first colliding sample of a path.

    ``shapes`` are the two names (the second 'table', a keep-out box's name, or a link),
    ``kind`` 'table', 'self' or 'keep_out', ``depth`` [m] how far the first is into the second
    (for the table: into the margin), ``sample`` its index among the dense samples,
    ``waypoint`` the segment it lies on (between waypoints ``waypoint`` and ``waypoint`` + 1),
    ``fraction`` how far along the path (0 to 1, of the joint travel), ``q`` (n,) [rad].
    """

    shapes: tuple
    kind: str
    depth: float
    sample: int
    waypoint: int
    fraction: float
    q: np.ndarray

    def describe(self, margin: float = 0.0) -> str:
        """Return the contact in words: which shapes, how deep, where along the path."""
        a, b = self.shapes
        mm = self.depth * 1e3
        where = f'at {self.fraction * 100:.0f} % of the path'
        if self.kind == 'table':
            into = 'the table margin' if margin > 0.0 else 'the table'
            return f'{a} is {mm:.0f} mm into {into} {where}'
        if self.kind == 'keep_out':
            return f'{a} is {mm:.0f} mm inside {b} {where}'
        return f'{a} and {b} overlap by {mm:.0f} mm (self-collision) {where}'


@dataclass(frozen=True)
class PathCheck:
    """The verdict on a path: ``first`` contact (None when free) and the clearances [m]."""

    first: Contact | None
    clearance: dict          # kind -> smallest clearance along the path [m] (< 0: collides)
    n_samples: int

    @property
    def free(self) -> bool:
        """Return True when no sample collides."""
        return self.first is None


def densify(waypoints: np.ndarray, max_joint_step: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return samples (m, n) of the straight joint-space lines through ``waypoints`` (N, n).

    No joint moves more than ``max_joint_step`` [rad] between two samples; each waypoint is a
    sample. Also returns the segment (m,) each sample starts on.
    """
    W = np.asarray(waypoints, dtype=float)
    if len(W) < 2:
        return W.copy(), np.zeros(len(W), dtype=int)
    steps = np.abs(np.diff(W, axis=0)).max(axis=1)
    counts = np.maximum(1, np.ceil(steps / max_joint_step - 1e-9).astype(int))
    segment = np.repeat(np.arange(len(counts)), counts)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    s = (np.arange(counts.sum()) - first[segment]) / counts[segment]
    Q = W[segment] + s[:, None] * (W[segment + 1] - W[segment])
    return np.vstack([Q, W[-1:]]), np.append(segment, len(counts) - 1)


class CollisionChecker:
    """Check configurations and swept joint paths of ``arm`` against its ``geometry``."""

    def __init__(self, arm: ArmModel, settings: CollisionSettings | None = None,
                 geometry: CollisionGeometry | None = None):
        """Build the geometry of ``arm`` from ``settings`` (or take ``geometry``) in MuJoCo."""
        self.arm = arm
        self.settings = CollisionSettings() if settings is None else settings
        s = self.settings
        self.geometry = geometry or build_geometry(arm, s.tool, s.table_margin, s.keep_out)
        self.model = mujoco.MjModel.from_xml_string(collision_mjcf(self.geometry))
        # Contacts are reported up to HORIZON apart (the clearances), the table's up to its
        # margin further.
        self.model.geom_margin[:] = HORIZON
        table = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, TABLE)
        self.model.geom_margin[table] = HORIZON + self.geometry.table_margin
        # MuJoCo's midphase (each body's bounding-volume tree, built when the model compiles)
        # does not see the margins set here: it dropped pairs within them (the table margin
        # against link1 at any margin; 4 of 2,000 random configurations colliding at the
        # shipped 20 mm margin taken as free). Every pair goes to the broad phase instead.
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
        self.data = mujoco.MjData(self.model)
        self._qadr = np.array([self.model.jnt_qposadr[mujoco.mj_name2id(
            self.model, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in arm.joint_names])
        # The joints' positions as one slice of qpos when they are in order (a view: no copy).
        first = int(self._qadr[0]) if len(self._qadr) else 0
        self._qslice = (slice(first, first + len(self._qadr))
                        if np.array_equal(self._qadr, first + np.arange(len(self._qadr)))
                        else None)
        names = {shape.name.replace(' ', '_'): shape.name for shape in self.geometry.shapes}
        names.update({box.name.replace(' ', '_'): box.name for box in self.geometry.keep_out})
        self._names, kind = [], []
        for g in range(self.model.ngeom):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g)
            self._names.append(names.get(name, name))
            kind.append(2 if name == TABLE else 1 if name.startswith('keep-out') else 0)
        self._kind = np.array(kind)          # 0: the arm, 1: a keep-out box, 2: the table
        self._table_margin = self.geometry.table_margin

    def _contacts(self, Q):
        """
        Return (sample, geom1, geom2, distance) of every contact within the horizon.

        The loop runs once per sample (thousands per path): it keeps to the two MuJoCo calls,
        one read of the contact list where there are contacts (two arrays copied), and
        Python lists; the sample index of each contact is made at the end from the counts.
        """
        m, d = self.model, self.data
        qpos = d.qpos[self._qslice] if self._qslice is not None else None
        kinematics, collision = mujoco.mj_kinematics, mujoco.mj_collision
        geoms, dists, counts = [], [], []
        for q in Q:
            if qpos is not None:
                qpos[:] = q
            else:
                d.qpos[self._qadr] = q
            kinematics(m, d)
            collision(m, d)
            n = d.ncon
            counts.append(n)
            if n:
                c = d.contact
                geoms.append(c.geom.copy())
                dists.append(c.dist.copy())
        if not geoms:
            return (np.zeros(0, dtype=int),) * 3 + (np.zeros(0),)
        sample = np.repeat(np.arange(len(counts)), counts)
        g = np.concatenate(geoms)
        return sample, g[:, 0].copy(), g[:, 1].copy(), np.concatenate(dists)

    def check_configurations(self, Q: np.ndarray, segment: np.ndarray | None = None,
                             fraction: np.ndarray | None = None,
                             escape: bool = False) -> PathCheck:
        """
        Return the ``PathCheck`` of samples (m, n) as they are (no samples added).

        ``escape`` True: the first sample is where the arm is now, and a contact it is already
        in does not count as long as that pair gets no deeper (by 0.1 mm) along the path, so
        an arm that is touching something can still be moved away from it.
        """
        Q = np.asarray(Q, dtype=float).reshape(-1, self.arm.n_joints)
        m = len(Q)
        if not self.settings.enabled or m == 0:
            return PathCheck(None, {}, m)
        sample, g1, g2, dist = self._contacts(Q)
        k1, k2 = self._kind[g1], self._kind[g2]
        kind = np.where((k1 == 2) | (k2 == 2), 2, np.where((k1 == 1) | (k2 == 1), 1, 0))
        clear = dist - np.where(kind == 2, self._table_margin, 0.0)
        clearance = {}
        for code, word in KINDS.items():
            if code == 1 and not self.geometry.keep_out:
                continue
            sel = clear[kind == code]
            cap = HORIZON + (self._table_margin if code == 2 else 0.0)
            clearance[word] = float(sel.min()) if sel.size else cap
            clearance[word] = min(clearance[word], cap)
        colliding = clear < 0.0
        if escape and np.any(colliding & (sample == 0)):
            key = g1 * self.model.ngeom + g2
            start = colliding & (sample == 0)
            allowed = dict(zip(key[start].tolist(), clear[start].tolist()))
            limit = np.array([allowed.get(k, 0.0) for k in key.tolist()]) - ESCAPE_TOLERANCE
            colliding &= clear < limit
        hit = np.flatnonzero(colliding)
        if len(hit) == 0:
            return PathCheck(None, clearance, m)
        first = int(sample[hit].min())
        at = hit[sample[hit] == first]
        c = at[np.argmin(clear[at])]
        a, b = self._names[g1[c]], self._names[g2[c]]
        if self._kind[g1[c]] > 0 or (kind[c] == 0 and g1[c] < g2[c]):
            a, b = b, a            # the arm's shape first; of two links, the outer one
        segment = np.zeros(m, dtype=int) if segment is None else segment
        if fraction is None:
            travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(Q, axis=0)).max(axis=1))])
            fraction = travel / travel[-1] if travel[-1] > 0.0 else np.zeros(m)
        return PathCheck(Contact((a, b), KINDS[int(kind[c])], float(-clear[c]), first,
                                 int(segment[first]), float(fraction[first]), Q[first].copy()),
                         clearance, m)

    def check_path(self, waypoints: np.ndarray, max_joint_step: float | None = None,
                   escape: bool = False) -> PathCheck:
        """
        Return the ``PathCheck`` of the straight joint-space motion through ``waypoints``.

        Samples every ``max_joint_step`` [rad] (default the settings') between waypoints;
        ``escape`` as ``check_configurations``.
        """
        W = np.asarray(waypoints, dtype=float).reshape(-1, self.arm.n_joints)
        if not self.settings.enabled:
            return PathCheck(None, {}, 0)
        Q, segment = densify(W, max_joint_step or self.settings.max_joint_step)
        return self.check_configurations(Q, segment, escape=escape)

    def message(self, check: PathCheck) -> str:
        """Return the first contact of ``check`` in words ('' when free)."""
        if check.free:
            return ''
        return check.first.describe(self.geometry.table_margin)
