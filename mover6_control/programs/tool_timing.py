"""
Time-optimal timing of a joint path with the tool's speed bounded where a lin or circ runs.

The path and the timing are ``motion.timing.time_optimal.time_parameterize``'s (the blended
path through the waypoints, corners rounded within ``max_deviation``, TOPP-RA passes over its
grid), with one more cap at every grid point (its ``path_caps``): where the waypoint before
it belongs to a move with a tool speed ``v`` [m/s] and turn rate ``w`` [rad/s], the path speed
is held to ``sdot <= min(v / |J_v q'|, w / |J_w q'|)`` (``J`` the geometric Jacobian), so the
flange moves no faster than commanded. The joint speed and acceleration limits hold as in
``time_parameterize``.
"""

from __future__ import annotations

from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import jacobian_batch
from mover6_control.motion.blended_path import BlendedPath
from mover6_control.motion.timing.path_timing import PathTrajectory
from mover6_control.motion.timing.time_optimal import time_parameterize
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


class ToolSpeedCaps:
    """
    The ``path_caps`` of ``time_parameterize`` for waypoints owned by moves with tool speeds.

    ``speed`` and ``rot`` (m,) are the tool speed [m/s] and turn rate [rad/s] of the move each
    waypoint of ``Q`` (m, n) ends (``inf``: no tool bound, a ptp), applied from the waypoint
    before it: each grid point takes the bound of the move its path position lies in (the
    waypoints' arc lengths split the path).
    """

    def __init__(self, arm: ArmModel, Q: np.ndarray, speed: np.ndarray, rot: np.ndarray):
        """Keep the arm and the bounds of the waypoints ``blended_path`` keeps of ``Q``."""
        Q = np.asarray(Q, dtype=float)
        keep = np.concatenate([[True], np.linalg.norm(np.diff(Q, axis=0), axis=1) > 1e-12])
        self.arm = arm
        self.speed = np.asarray(speed, dtype=float)[keep] * (1.0 - TOOL_MARGIN)
        self.rot = np.asarray(rot, dtype=float)[keep] * (1.0 - TOOL_MARGIN)

    def __call__(self, path: BlendedPath, s_grid: np.ndarray) -> np.ndarray:
        """Return the caps on ``sdot^2`` at ``s_grid`` (N + 1,), ``inf`` where none."""
        k = np.clip(np.searchsorted(np.asarray(path.waypoint_s), s_grid, side='right'), 1,
                    len(self.speed) - 1)
        caps = np.full(s_grid.shape, np.inf)
        bounded = np.flatnonzero(np.isfinite(self.speed[k]) | np.isfinite(self.rot[k]))
        if bounded.size:
            s = s_grid[bounded]
            q, dq = path.evaluate(s, path.segment_of(s), (0, 1))
            caps[bounded] = tool_caps(self.arm, q, dq, self.speed[k[bounded]],
                                      self.rot[k[bounded]])
        return caps


def timed_path(arm: ArmModel, Q: np.ndarray, owner_speed: np.ndarray,
               owner_rot: np.ndarray, v_max: np.ndarray, a_max: np.ndarray,
               max_deviation: float = 1e-3, n_grid: int | None = None) -> PathTrajectory:
    """
    Return the time-optimal ``PathTrajectory`` through waypoints ``Q`` (m, n), rest to rest.

    ``owner_speed`` and ``owner_rot`` (m,) are the tool speed [m/s] and turn rate [rad/s] of the
    move each waypoint ends (``ToolSpeedCaps``); ``v_max``, ``a_max`` (n,) the joint limits.
    Raises ``UnreachableError`` ('not_controllable') when the path cannot be timed.
    """
    return time_parameterize(Q, v_max, a_max, max_deviation=max_deviation, n_grid=n_grid,
                             path_caps=ToolSpeedCaps(arm, Q, owner_speed, owner_rot))
