"""
The pairs of the Mover6's links that can never meet: left out of self-collision.

Links two apart (link i and link i + 2) move against each other by the two joints between them
only. ``never_meeting_pairs`` sweeps those two joints over a grid across the widest limits of
any limit set and takes the smallest distance between the two links' shapes (MuJoCo's
``mj_geomDistance``). Between grid points the distance can fall by at most the grid's half step
times how far the later link's shapes reach from each joint's axis (a rotation by ``d`` moves a
point ``r`` from the axis by at most ``r d``; ``_Pose.reach`` bounds ``r`` at every angle),
so a pair whose smallest distance on the grid exceeds that bound (by ``KEEP``) cannot touch
anywhere in the limits: it is left out, with the figure that shows it. Such a pair would
otherwise sit permanently close (the elbow housing and the forearm's tube, a few millimetres
apart at every angle) and make the reported self clearance say nothing about the pairs that
can meet.

Only link pairs are swept (the base is the world's and carries the table; the flange carries
the tool, whose size is a parameter). ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.kinematics.arm import ArmModel
import mujoco
import numpy as np

KEEP = 0.0            # [m] a pair left out stays at least this far apart at every angle
COARSE = (np.radians(1.0), np.radians(4.0))   # [rad] the first grid's steps of the two joints


@dataclass(frozen=True)
class PairSweep:
    """Links ``bodies`` (i, j): ``closest`` [m] on the grid, ``bound`` [m] the grid's error."""

    bodies: tuple
    joints: tuple
    closest: float
    bound: float

    @property
    def never_meet(self) -> bool:
        """Return True when the pair stays more than ``KEEP`` apart at every angle."""
        return self.closest - self.bound > KEEP


class _Pose:
    """Poses links ``i`` and ``i + 2`` of a ``collision_mjcf`` model at the two joints between."""

    def __init__(self, model: mujoco.MjModel, arm: ArmModel, i: int):
        self.model, self.data = model, mujoco.MjData(model)
        body = {k: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                     f'{arm.joint_names[k - 1]}_link') for k in (i, i + 2)}
        self.geoms = {k: [g for g in range(model.ngeom) if model.geom_bodyid[g] == body[k]]
                      for k in (i, i + 2)}
        self.joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, arm.joint_names[k])
                       for k in (i, i + 1)]
        self.qadr = [model.jnt_qposadr[j] for j in self.joints]

    def put(self, a: float, b: float) -> None:
        self.data.qpos[:] = 0.0
        self.data.qpos[self.qadr[0]], self.data.qpos[self.qadr[1]] = a, b
        mujoco.mj_kinematics(self.model, self.data)

    def distance(self, g1: int, g2: int) -> float:
        return mujoco.mj_geomDistance(self.model, self.data, g1, g2, 1.0, None)

    def reach(self, g: int) -> np.ndarray:
        """
        Return how far [m] geom ``g`` (segment ends plus radius) can reach from each axis.

        From the second joint's axis: as it is (turning either joint keeps it). From the
        first joint's: the second joint's anchor's distance from it plus how far the geom
        reaches from that anchor, which no angle of the second joint changes.
        """
        d = self.data
        half = self.model.geom_size[g]
        along = d.geom_xmat[g].reshape(3, 3)[:, 2] * half[1]
        ends = np.array([d.geom_xpos[g] - along, d.geom_xpos[g] + along])
        first, second = self.joints

        def radial(points, j):
            rel = np.atleast_2d(points) - d.xanchor[j]
            return np.linalg.norm(rel - np.outer(rel @ d.xaxis[j], d.xaxis[j]), axis=1)

        r = float(half[0])
        anchor = d.xanchor[second]
        from_first = (float(radial(anchor, first)[0])
                      + float(np.linalg.norm(ends - anchor, axis=1).max()) + r)
        return np.array([from_first, float(radial(ends, second).max()) + r])


def _grid(lower: float, upper: float, step: float) -> np.ndarray:
    return np.linspace(lower, upper, max(int(np.ceil((upper - lower) / step)), 1) + 1)


def _sweep(pose: _Pose, pairs: list, grids: list) -> np.ndarray:
    """Return the smallest distance (len(pairs),) of each geom pair over the grid."""
    out = np.full(len(pairs), np.inf)
    for a in grids[0]:
        for b in grids[1]:
            pose.put(a, b)
            for k, (g1, g2) in enumerate(pairs):
                out[k] = min(out[k], pose.distance(g1, g2))
    return out


def sweep_pair(model: mujoco.MjModel, arm: ArmModel, i: int, lower: np.ndarray,
               upper: np.ndarray) -> PairSweep:
    """
    Return the ``PairSweep`` of links ``i`` and ``i + 2`` of ``model`` (``collision_mjcf``).

    A first grid (``COARSE``) settles the shape pairs that stay far apart; each other shape
    pair is swept again on a grid fine enough that its error bound is half its first figure.
    """
    pose = _Pose(model, arm, i)
    pairs = [(g1, g2) for g1 in pose.geoms[i] for g2 in pose.geoms[i + 2]]
    pose.put(0.0, 0.0)
    reach = [pose.reach(g2) for _, g2 in pairs]
    limits = [(lower[k], upper[k]) for k in (i, i + 1)]
    grids = [_grid(lo, hi, h) for (lo, hi), h in zip(limits, COARSE)]
    steps = np.array([g[1] - g[0] if len(g) > 1 else 0.0 for g in grids])
    closest = _sweep(pose, pairs, grids)
    bound = np.array([0.5 * float(r @ steps) for r in reach])
    for k in np.flatnonzero(closest - bound <= KEEP):
        if closest[k] <= KEEP:
            continue                       # they do meet (or nearly): nothing to refine
        fine = [0.5 * (closest[k] - KEEP) / max(r, 1e-9) for r in reach[k]]
        fine_grids = [_grid(lo, hi, min(h, c)) for (lo, hi), h, c in zip(limits, fine, COARSE)]
        fine_steps = np.array([g[1] - g[0] if len(g) > 1 else 0.0 for g in fine_grids])
        closest[k] = _sweep(pose, [pairs[k]], fine_grids)[0]
        bound[k] = 0.5 * float(reach[k] @ fine_steps)
    worst = int(np.argmin(closest - bound))
    return PairSweep((i, i + 2), (arm.joint_names[i], arm.joint_names[i + 1]),
                     float(closest[worst]), float(bound[worst]))


def never_meeting_pairs(model: mujoco.MjModel, arm: ArmModel, lower: np.ndarray,
                        upper: np.ndarray) -> list:
    """Return the ``PairSweep`` of every pair of links two apart, link1 .. link5."""
    return [sweep_pair(model, arm, i, lower, upper) for i in range(1, arm.n_joints - 2)]
