"""
The profiles: every time law the controller can time a motion by, and its settings.

A profile turns the start state and the waypoints (N, n) [rad] into a ``MotionPlan``
(``control.motion_plan``; ``control.planners.plan_motion`` builds it). The profiles
(``PROFILES``):

- ``synchronised``: the Mover6 report eq. 1-2. Per waypoint, the joint with the furthest to go
  moves at ``lambda_max`` and sets ``t_max``; every joint moves at ``(q_k - q_{k-1}) / t_max`` so
  all arrive together; the arm stops at each waypoint.
- ``trapezoidal``: the Mover6 report eq. 16-18 per waypoint: ``V_max = |dq| / (t_max - t_blend)``,
  ramps of ``t_blend`` (default ``t_max / 4``); stops at each waypoint. The profile is the one
  of ``motion.time_laws.trapezoidal``.
- ``jerk_limited``: ruckig, rest to rest per waypoint, within velocity, ``a_max`` and ``j_max``
  (``motion.jerk_limited.ruckig_trajectory``).
- ``continuous``: the time-optimal trajectory along the blended path through all waypoints,
  without stopping at each (``motion.time_optimal.time_parameterize``).
- ``cubic``, ``quintic`` (3-4-5), ``septic`` (4-5-6-7), ``sharp_trapezoid``: the time laws of
  the Jacobians and trajectories report, one synchronised move per waypoint, stopping at each,
  each move the shortest within the velocity limits and ``a_max``
  (``motion_plan.time_law_segment``).
- ``cubic_spline``, ``quintic_spline``, ``bspline``, ``multi_trapezoid``: the multi-point
  trajectories of the same report through (or, B-spline and blends, near) all waypoints without
  stopping, fitted to the velocity limits and ``a_max`` by one common time factor.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing import time_laws
from mover6_control.motion.timing.spline_trajectories import (bspline_trajectory,
                                                              cubic_trajectory,
                                                              multipoint_trapezoidal,
                                                              quintic_trajectory)
from mover6_control.motion.timing.time_laws import trapezoid_times
from mover6_control.parameters import CONTROLLER, PROFILES   # the defaults, the laws' names
from mover6_control.validation import as_positive

# Per waypoint, stopping at each: the time laws of the Jacobians and trajectories report, each
# move as short as the velocity limits and a_max allow (``trajectories.point_to_point``).
STOP_AT_EACH_PROFILES = {'cubic': time_laws.cubic, 'quintic': time_laws.quintic,
                         'septic': time_laws.septic,
                         'sharp_trapezoid': time_laws.sharp_trapezoid}
# Through every waypoint without stopping: the multi-point trajectories of the same report,
# fitted to the velocity limits and a_max by one common time factor.
THROUGH_ALL_PROFILES = {
    'cubic_spline': lambda Q, v, a: cubic_trajectory(Q, v_max=v, a_max=a),
    'quintic_spline': lambda Q, v, a: quintic_trajectory(Q, v_max=v, a_max=a),
    'bspline': lambda Q, v, a: bspline_trajectory(Q, v_max=v, a_max=a),
    'multi_trapezoid': lambda Q, v, a: multipoint_trapezoidal(Q, v, a),
}
# The families the report's figure compares (``tools.plots.profile_comparison``).
PROFILE_FAMILIES = {
    'stop at each waypoint': ('synchronised', 'trapezoidal', 'jerk_limited', 'cubic', 'quintic',
                              'septic', 'sharp_trapezoid'),
    'through all waypoints': ('continuous', 'cubic_spline', 'quintic_spline', 'bspline',
                              'multi_trapezoid'),
}


@dataclass(frozen=True)
class LawConfig:
    """
    Which profile, and the parameters of the profiles.

    ``lambda_max`` [rad/s] (synchronised), ``t_max`` [s] and ``t_blend`` [s] (trapezoidal; 0 or
    None means ``t_max / 4``), ``a_max`` [rad/s^2] and ``j_max`` [rad/s^3] (jerk-limited,
    continuous, and the deceleration of every law when stopping or replacing a motion).
    """

    profile: str = CONTROLLER['profile'].default
    lambda_max: float = CONTROLLER['lambda_max'].default
    t_max: float = CONTROLLER['t_max'].default
    t_blend: float = CONTROLLER['t_blend'].default
    a_max: float = CONTROLLER['a_max'].default
    j_max: float = CONTROLLER['j_max'].default

    def __post_init__(self):
        """Check the profile name and that every parameter is a positive number."""
        if self.profile not in PROFILES:
            raise InvalidInputError(f'profile must be one of {PROFILES}, got "{self.profile}"')
        for name in ('lambda_max', 't_max', 'a_max', 'j_max'):
            as_positive(getattr(self, name), name)
        trapezoid_times(self.t_max, self.blend)

    @property
    def blend(self) -> float:
        """Return ``t_blend`` [s], defaulting to ``t_max / 4`` (the Mover6 report)."""
        return self.t_max / 4.0 if self.t_blend in (None, 0.0) else float(self.t_blend)
