"""
Time-optimal timing of a joint path with the tool's speed bounded where a lin or circ runs.

The path is the time-optimal solver's (``motion.blended_path`` through the waypoints, corners
rounded within ``max_deviation``) and so is the timing (``motion.timing.time_optimal``'s
TOPP-RA passes over its grid), with one more cap at every grid point: where the waypoint before
it belongs to a move with a tool speed ``v`` [m/s] and turn rate ``w`` [rad/s], the path speed
is held to ``sdot <= min(v / |J_v q'|, w / |J_w q'|)`` (``J`` the geometric Jacobian), so the
flange moves no faster than commanded. The joint speed and acceleration limits hold as in
``time_parameterize``; the result is checked on samples (``tool_speed_ratio``).
"""

from __future__ import annotations

from mover6_control.errors import UnreachableError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import jacobian_batch
from mover6_control.motion.blended_path import blended_path
from mover6_control.motion.timing import topp_pieces
from mover6_control.motion.timing.path_timing import GridTiming, PathTrajectory, ScaledTiming
from mover6_control.motion.timing.time_optimal import (_backward_pass, _forward_pass, _grid,
                                                       _interval_ends, _LIMIT_MARGIN,
                                                       _speed_caps, _within_limits)
import numpy as np

# The tool speed caps are planned this much below the commanded speeds: between grid points
# the speed can pass a cap by a small fraction of it.
TOOL_MARGIN = 2e-2


def tool_caps(arm: ArmModel, q: np.ndarray, dq: np.ndarray, v: np.ndarray,
              w: np.ndarray) -> np.ndarray:
    """Return the largest ``sdot^2`` (m,) the tool speeds ``v``, ``w`` (m,) allow at ``q``."""
    J = jacobian_batch(arm, q)
    lin = np.linalg.norm(np.einsum('mij,mj->mi', J[:, :3], dq), axis=1)
    rot = np.linalg.norm(np.einsum('mij,mj->mi', J[:, 3:], dq), axis=1)
    with np.errstate(divide='ignore', invalid='ignore'):
        cap = np.minimum(np.where(lin > 0, v / lin, np.inf), np.where(rot > 0, w / rot, np.inf))
    return cap ** 2


def timed_path(arm: ArmModel, Q: np.ndarray, owner_speed: np.ndarray,
               owner_rot: np.ndarray, v_max: np.ndarray, a_max: np.ndarray,
               max_deviation: float = 1e-3, n_grid: int | None = None) -> PathTrajectory:
    """
    Return the time-optimal ``PathTrajectory`` through waypoints ``Q`` (m, n), rest to rest.

    ``owner_speed`` and ``owner_rot`` (m,) are the tool speed [m/s] and turn rate [rad/s] of the
    move each waypoint ends (``inf``: no tool bound, a ptp), applied from the waypoint before
    it; ``v_max``, ``a_max`` (n,) the joint limits. Raises ``UnreachableError``
    ('not_controllable') when the path cannot be timed.
    """
    path = blended_path(Q, max_deviation, 'arc')
    v = np.asarray(v_max, dtype=float) * (1.0 - _LIMIT_MARGIN)
    a = np.asarray(a_max, dtype=float) * (1.0 - _LIMIT_MARGIN)
    if n_grid is None:
        n_grid = max(400, 20 * path.waypoints.shape[0])
    s_grid, seg = _grid(path, n_grid)
    N = seg.size
    delta = np.diff(s_grid)
    orders = (1, 2)
    d0 = dict(zip(orders, path.evaluate(s_grid[:-1], seg, orders)))
    d1, last = _interval_ends(path, s_grid, seg, d0, orders)
    cap0 = _speed_caps(d0[1], v)
    cap1 = np.empty(N)
    cap1[:-1] = cap0[1:]
    cap1[last] = _speed_caps(d1[1][last], v)
    x_cap = np.full(N + 1, np.inf)
    x_cap[:-1] = cap0
    x_cap[1:] = np.minimum(x_cap[1:], cap1)
    # The tool caps: each grid point takes the bound of the move its path position lies in
    # (the waypoints' arc lengths split the path; repeats were dropped by blended_path, so
    # the owners follow the kept waypoints).
    keep = _kept_rows(Q)
    speeds, rots = np.asarray(owner_speed)[keep], np.asarray(owner_rot)[keep]
    k = np.clip(np.searchsorted(np.asarray(path.waypoint_s), s_grid, side='right'), 1,
                len(speeds) - 1)
    bounded = np.isfinite(speeds[k]) | np.isfinite(rots[k])
    if np.any(bounded):
        idx = np.flatnonzero(bounded)
        seg_at = path.segment_of(s_grid[idx])
        q, dq = path.evaluate(s_grid[idx], seg_at, (0, 1))
        caps = tool_caps(arm, q, dq, speeds[k[idx]] * (1.0 - TOOL_MARGIN),
                         rots[k[idx]] * (1.0 - TOOL_MARGIN))
        x_cap[idx] = np.minimum(x_cap[idx], caps)
    x_cap[-1] = 0.0
    backward, forward = topp_pieces.pieces((d0[1], d0[2], d1[1], d1[2]), delta, a, x_cap[:-1])
    hi = _backward_pass(backward)
    x, u = _forward_pass(forward, delta, hi, 0.0)
    sd = np.sqrt(x)
    dt = 2.0 * delta / np.maximum(sd[:-1] + sd[1:], 1e-300)
    if not np.all(np.isfinite(dt)):
        raise UnreachableError('the path cannot be timed: the speed stays zero',
                               reason='not_controllable')
    timing = GridTiming(s_grid, sd, u, np.concatenate([[0.0], np.cumsum(dt)]))
    traj = _within_limits(path, timing, PathTrajectory(path, timing), v / (1.0 - _LIMIT_MARGIN),
                          a / (1.0 - _LIMIT_MARGIN), seg, (d0[1], d0[2], d1[1], d1[2]))
    return traj


def _kept_rows(Q):
    """Return the rows of ``Q`` that ``blended_path`` keeps (consecutive repeats dropped)."""
    Q = np.asarray(Q, dtype=float)
    return np.concatenate([[True], np.linalg.norm(np.diff(Q, axis=0), axis=1) > 1e-12])


def slowed(traj: PathTrajectory, factor: float) -> PathTrajectory:
    """Return ``traj`` slowed uniformly by ``factor`` >= 1 (the same path)."""
    return PathTrajectory(traj.path, ScaledTiming(traj.timing, factor))
