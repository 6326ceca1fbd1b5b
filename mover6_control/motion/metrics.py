"""
Trajectory metrics: duration, path length, peak rates and Cartesian deviation from the path.

Everything is measured on samples at a fixed time step ``dt`` [s], the way a controller would
see the trajectory. Jerk is the finite difference of sampled acceleration, so a step in
acceleration of size ``da`` shows as ``da / dt``: trajectories with acceleration steps
(trapezoids, TOPP) report the jerk a ``dt``-period controller would command.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, TYPE_CHECKING

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_finite_array, as_positive
import numpy as np

if TYPE_CHECKING:
    from mover6_control.motion.timing.trajectories import JointTrajectory

# Points x segments handled per block when measuring distances to a polyline.
_BLOCK = 2_000_000


@dataclass(frozen=True, eq=False)
class TrajectoryMetrics:
    """Figures of one sampled trajectory; Cartesian figures are NaN when no FK was given."""

    duration: float                 # [s]
    joint_path_length: float        # [rad] arc length in joint space
    path_length: float              # [m] tool path length (FK), NaN without FK
    peak_velocity: np.ndarray       # (n,) [rad/s]
    peak_acceleration: np.ndarray   # (n,) [rad/s^2]
    peak_jerk: np.ndarray           # (n,) [rad/s^3], finite difference at dt
    max_deviation: float            # [m] largest distance of the tool from the intended path
    dt: float                       # [s] sampling step used


def sample_times(duration: float, dt: float) -> np.ndarray:
    """Return times (m,) from 0 to ``duration`` [s] every ``dt`` [s], the end included."""
    dt = as_positive(dt, 'dt')
    t = np.arange(0.0, duration, dt)
    return np.append(t, duration) if t.size == 0 or t[-1] < duration else t


def max_deviation_from_polyline(points: np.ndarray, polyline: np.ndarray) -> float:
    """
    Return the largest distance [m] from any of ``points`` (m, 3) to the polyline (k, 3).

    The polyline is the chain of segments between consecutive vertices; k = 1 is a point.
    """
    pts = as_finite_array(points, (None, 3), 'points')
    poly = as_finite_array(polyline, (None, 3), 'polyline')
    if pts.shape[0] == 0 or poly.shape[0] == 0:
        raise InvalidInputError('points and polyline must not be empty')
    if poly.shape[0] == 1:
        return float(np.linalg.norm(pts - poly[0], axis=1).max())
    a = poly[:-1]
    ab = poly[1:] - a
    ab2 = np.einsum('ij,ij->i', ab, ab)
    ab2 = np.where(ab2 > 0.0, ab2, 1.0)
    rows = max(1, _BLOCK // a.shape[0])
    worst = 0.0
    for start in range(0, pts.shape[0], rows):
        p = pts[start:start + rows, None, :]
        t = np.clip(np.einsum('mkj,kj->mk', p - a, ab) / ab2, 0.0, 1.0)
        d = np.linalg.norm(p - (a + t[..., None] * ab), axis=2).min(axis=1)
        worst = max(worst, float(d.max()))
    return worst


def _tool_positions(fk_fn, Q):
    out = np.asarray(fk_fn(Q), dtype=float)
    if out.ndim == 3 and out.shape[1:] == (4, 4):
        return out[:, :3, 3]
    if out.ndim == 2 and out.shape[1] == 3:
        return out
    raise InvalidInputError(f'fk_fn must return (m, 4, 4) poses or (m, 3) points, got {out.shape}')


def trajectory_metrics(traj: JointTrajectory,
                       fk_fn: Optional[Callable[[np.ndarray], np.ndarray]] = None,
                       desired_positions: Optional[np.ndarray] = None,
                       dt: float = 1e-3) -> TrajectoryMetrics:
    """
    Return ``TrajectoryMetrics`` of a ``JointTrajectory`` sampled every ``dt`` [s].

    ``fk_fn(Q (m, n)) -> (m, 4, 4) or (m, 3)`` gives tool positions, e.g.
    ``lambda Q: forward.fk_batch(arm, Q)``; with it the tool path length is measured, and
    with ``desired_positions`` (k, 3) [m] (the intended path as a polyline, e.g. the positions
    of the planned poses) the largest deviation of the tool from it.
    """
    t = sample_times(traj.duration, dt)
    Q, QD, QDD = traj.sample(t)
    jerk = np.abs(np.diff(QDD, axis=0)) / np.diff(t)[:, None] if t.size > 1 \
        else np.zeros((1, Q.shape[1]))
    joint_len = float(np.linalg.norm(np.diff(Q, axis=0), axis=1).sum())
    path_len = deviation = float('nan')
    if fk_fn is not None:
        P = _tool_positions(fk_fn, Q)
        path_len = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
        if desired_positions is not None:
            deviation = max_deviation_from_polyline(P, desired_positions)
    elif desired_positions is not None:
        raise InvalidInputError('desired_positions needs fk_fn to compute tool positions')
    return TrajectoryMetrics(
        duration=float(traj.duration), joint_path_length=joint_len, path_length=path_len,
        peak_velocity=np.abs(QD).max(axis=0), peak_acceleration=np.abs(QDD).max(axis=0),
        peak_jerk=jerk.max(axis=0), max_deviation=deviation, dt=float(dt))
