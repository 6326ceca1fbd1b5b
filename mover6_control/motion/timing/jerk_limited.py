"""
Jerk-limited, time-optimal, synchronised point-to-point moves by ruckig.

The one ruckig wrapper: ``ruckig_trajectory`` plans the move (from a moving state too) and
``RuckigTrajectory`` plays it behind the ``motion.trajectories`` interface; the controller's
jerk-limited profile plays it too.
"""

from __future__ import annotations

from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing.trajectories import JointTrajectory, Limit
from mover6_control.validation import as_finite_array, as_positive
import numpy as np
import ruckig


class RuckigTrajectory(JointTrajectory):
    """A ruckig ``Trajectory`` behind the common interface; jerk is piecewise constant."""

    def __init__(self, trajectory: object, n_joints: int):
        super().__init__(trajectory.duration, n_joints)
        self._trajectory = trajectory

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(q, qd)`` (n,) each at one time ``t`` [s], straight from ruckig."""
        q, qd, _ = self._trajectory.at_time(self._time(t))
        return np.asarray(q, dtype=float), np.asarray(qd, dtype=float)

    def _evaluate(self, t):
        q = np.empty((t.size, self._n_joints))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        for i, ti in enumerate(t):
            q[i], qd[i], qdd[i] = self._trajectory.at_time(float(ti))
        return q, qd, qdd, self._jerk(t)

    def _jerk(self, t):
        # Ruckig's acceleration is piecewise linear: a one-sided difference inside a piece is
        # exact. Step away from the end so the difference stays inside [0, duration].
        h = 1e-7
        jerk = np.empty((t.size, self._n_joints))
        for i, ti in enumerate(t):
            lo = min(float(ti), max(self._duration - h, 0.0))
            a0 = np.asarray(self._trajectory.at_time(lo)[2])
            a1 = np.asarray(self._trajectory.at_time(lo + h)[2])
            jerk[i] = (a1 - a0) / h if self._duration > 0.0 else 0.0
        return jerk


def ruckig_trajectory(q0: Sequence[float], q1: Sequence[float], v_max: Limit, a_max: Limit,
                      j_max: Limit, qd0: Optional[Sequence[float]] = None,
                      qdd0: Optional[Sequence[float]] = None) -> RuckigTrajectory:
    """
    Return ruckig's jerk-limited, time-optimal move from ``q0`` to rest at ``q1``.

    All joints are synchronised (they finish together); ``qd0`` [rad/s] and ``qdd0``
    [rad/s^2] start it from a moving state, e.g. when a new goal preempts a running motion.
    ``v_max`` [rad/s], ``a_max`` [rad/s^2] and ``j_max`` [rad/s^3] are per joint (n,) or one
    value for all.
    """
    q0 = as_finite_array(q0, (None,), 'q0')
    n = q0.size
    q1 = as_finite_array(q1, (n,), 'q1')
    qd0 = np.zeros(n) if qd0 is None else as_finite_array(qd0, (n,), 'qd0')
    qdd0 = np.zeros(n) if qdd0 is None else as_finite_array(qdd0, (n,), 'qdd0')
    inp = ruckig.InputParameter(n)
    inp.current_position = q0.tolist()
    inp.current_velocity = qd0.tolist()
    inp.current_acceleration = qdd0.tolist()
    inp.target_position = q1.tolist()
    inp.target_velocity = [0.0] * n
    inp.target_acceleration = [0.0] * n
    inp.max_velocity = as_positive(v_max, 'v_max', n).tolist()
    inp.max_acceleration = as_positive(a_max, 'a_max', n).tolist()
    inp.max_jerk = as_positive(j_max, 'j_max', n).tolist()
    traj = ruckig.Trajectory(n)
    result = ruckig.Ruckig(n).calculate(inp, traj)
    if result not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise InvalidInputError(f'ruckig could not plan this move: {result}')
    return RuckigTrajectory(traj, n)
