"""
What the console's page computes, without a browser and without ROS.

- ``GoalConvention``: X Y Z A B C of the Mover6 report (``R = R_home Rz(A) Ry(B) Rx(C)``,
  ``R_home`` the flange at q = 0, as the goal command line takes them) to a pose and back;
- ``GoalRoute``: which planner topic a goal of a shape (and its via poses) goes to;
- ``Preview``: the plan of a goal made here, with the planner's own core and its settings, from
  the measured joints, moving nothing ("Plan"); a refusal names its reason and the closest pose
  reachable (the planner's, or the farthest reachable pose on the straight line to the goal);
- ``JogHold``: a jog command that lasts only while the user keeps giving it (released = stop).
"""

from dataclasses import dataclass, field
import threading
from typing import Optional, Sequence

from mover6_control.collision.checker import CollisionChecker
from mover6_control.errors import InvalidInputError, Mover6Error, UnreachableError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.ik_closed_form import ik_closed_form
from mover6_control.kinematics.rotations import (euler_zyx_near, goal_relative_to_start,
                                                 slerp)
from mover6_control.parameters import PATH_MOTIONS, POSE_MOTIONS
from mover6_control.planning.planner_core import (make_checker, plan_path_goal,
                                                  plan_pose_goal, PlannerSettings)
from mover6_control.planning.via_joint import plan_via_path_goal
from mover6_control.validation import as_finite_array
import numpy as np

SHAPES = ('linear', 'parabolic', 'spline', 'arc', 'joint')
LINE_STEPS = 24         # poses tried on the line to a refused goal (the closest reachable one)


class GoalConvention:
    """The goal numbers X Y Z [m] A B C [rad] of the Mover6 report, for one arm."""

    def __init__(self, arm: ArmModel):
        """Take the arm whose flange orientation at q = 0 is the angles' reference."""
        self.arm = arm
        self.home = fk(arm, np.zeros(arm.n_joints))

    def pose(self, numbers: Sequence[float]) -> np.ndarray:
        """Return the 4x4 transform of six numbers X Y Z A B C (else ``InvalidInputError``)."""
        values = as_finite_array(numbers, (6,), 'goal X Y Z A B C')
        return goal_relative_to_start(self.home, *values)

    def numbers(self, T: np.ndarray, ref: Sequence[float] = (0.0, 0.0, 0.0)) -> tuple:
        """Return X Y Z A B C of pose ``T``: of the equivalent angles those nearest ``ref``."""
        T = np.asarray(T, dtype=float)
        angles = euler_zyx_near(self.home[:3, :3].T @ T[:3, :3], ref)
        return tuple(float(v) for v in T[:3, 3]) + tuple(float(a) for a in angles)


@dataclass(frozen=True)
class GoalRoute:
    """Where a goal goes: ``kind`` 'pose' (PoseStamped) or 'path' (PoseArray), and its topic."""

    kind: str
    topic: str

    @staticmethod
    def of(shape: str, n_vias: int) -> 'GoalRoute':
        """Return the route of a goal of ``shape`` with ``n_vias`` via poses; refuse a misfit."""
        if shape not in SHAPES:
            raise InvalidInputError(f'shape must be one of {SHAPES}, got {shape!r}')
        if n_vias == 0 and shape in POSE_MOTIONS:
            return GoalRoute('pose', f'pose_goal/{shape}')
        if shape == 'joint' and n_vias == 1:
            return GoalRoute('path', 'path_goal/joint')
        if shape in PATH_MOTIONS and n_vias >= 1:
            if shape in ('arc', 'parabolic') and n_vias != 1:
                raise InvalidInputError(f'a {shape} goal takes exactly one via pose, '
                                        f'got {n_vias}')
            return GoalRoute('path', f'path_goal/{shape}')
        need = 'one via pose' if shape == 'joint' else 'no via pose'
        if shape in ('spline', 'arc'):
            need = 'at least one via pose' if shape == 'spline' else 'one via pose'
        raise InvalidInputError(f'a {shape} goal with {n_vias} via poses: it takes {need}')


@dataclass(frozen=True)
class PlanAnswer:
    """
    The answer to a goal: planned, with the tool path, or refused, with why.

    ``path`` (n, 3) [m] the flange positions of the plan (empty when refused); ``closest_q``
    the joints of the closest reachable pose, or None; ``closest_text`` says what it is.
    """

    planned: bool
    text: str
    reason: str = ''
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    closest_q: Optional[np.ndarray] = None
    closest_text: str = ''


class Preview:
    """Plan a goal here with the planner's core, moving nothing (the page's "Plan")."""

    def __init__(self, arm: ArmModel):
        """Take the arm the planner plans for (its limit set)."""
        self.arm = arm
        self._checker = (None, None)      # (settings, checker) of the latest plan
        # Two tabs may press Plan at once (viser's threads): one plan at a time, the collision
        # checker's MuJoCo data is one.
        self.lock = threading.Lock()

    def checker(self, settings: PlannerSettings) -> Optional[CollisionChecker]:
        """Return the collision checker of ``settings`` (built once per settings)."""
        if self._checker[0] != settings:
            self._checker = (settings, make_checker(self.arm, settings))
        return self._checker[1]

    def plan(self, q: np.ndarray, shape: str, T_goal: np.ndarray,
             vias: Sequence[np.ndarray] = (),
             settings: PlannerSettings = PlannerSettings()) -> PlanAnswer:
        """Return the ``PlanAnswer`` to ``T_goal`` of ``shape`` through ``vias`` from ``q``."""
        route = GoalRoute.of(shape, len(vias))
        with self.lock:
            return self._plan(route, q, shape, T_goal, vias, settings)

    def _plan(self, route, q, shape, T_goal, vias, settings):
        checker = self.checker(settings)
        try:
            if route.kind == 'pose':
                plan = plan_pose_goal(self.arm, q, T_goal, shape, settings, checker)
            elif shape == 'joint':
                plan = plan_via_path_goal(self.arm, q, np.asarray(vias), T_goal, settings,
                                          checker)
            else:
                plan = plan_path_goal(self.arm, q, np.asarray(vias), T_goal, shape, settings,
                                      checker)
        except UnreachableError as err:
            closest = err.details.get('closest_pose')
            return self.refusal(q, T_goal, str(err), err.reason, closest)
        except Mover6Error as err:
            return PlanAnswer(False, f'refused: {err}', 'invalid_goal')
        path = fk_batch(self.arm, plan.q)[:, :3, 3]
        return PlanAnswer(True, f'planned: {plan.motion}, {plan.n_waypoints} waypoints, '
                          f'{plan.path_length:.3f} m, about {plan.predicted_duration:.1f} s',
                          path=path)

    def refusal(self, q: np.ndarray, T_goal: np.ndarray, text: str, reason: str,
                closest: Optional[np.ndarray] = None) -> PlanAnswer:
        """Return a refusal with the closest reachable pose: ``closest`` or the line's."""
        if closest is not None:
            q_closest = self.solve(np.asarray(closest, dtype=float), q)
            if q_closest is not None:
                return PlanAnswer(False, f'refused ({reason}): {text}', reason,
                                  closest_q=q_closest,
                                  closest_text="the planner's closest pose inside the limits")
        q_line = self.closest_on_line(q, T_goal)
        what = ('the farthest reachable pose on the straight line to the goal'
                if q_line is not None else 'no reachable pose on the line to the goal')
        return PlanAnswer(False, f'refused ({reason}): {text}', reason, closest_q=q_line,
                          closest_text=what)

    def solve(self, T: np.ndarray, q_ref: np.ndarray) -> Optional[np.ndarray]:
        """Return the IK solution of ``T`` within the limits nearest ``q_ref``, or None."""
        solutions = ik_closed_form(self.arm, T, within_limits=True)
        if len(solutions) == 0:
            return None
        return solutions[np.argmin(np.abs(solutions - q_ref).max(axis=1))]

    def closest_on_line(self, q: np.ndarray, T_goal: np.ndarray) -> Optional[np.ndarray]:
        """Return the joints of the last pose with a solution on the line from the flange."""
        T_start = fk(self.arm, q)
        R = slerp([0.0, 1.0], np.stack([T_start[:3, :3], T_goal[:3, :3]]),
                  np.linspace(0.0, 1.0, LINE_STEPS + 1))
        best = None
        for k, s in enumerate(np.linspace(0.0, 1.0, LINE_STEPS + 1)):
            T = np.eye(4)
            T[:3, :3] = R[k]
            T[:3, 3] = (1.0 - s) * T_start[:3, 3] + s * T_goal[:3, 3]
            found = self.solve(T, q if best is None else best)
            if found is None:
                break
            best = found
        return best


class JogHold:
    """
    A jog command that lasts ``hold`` [s] after it was last given, then is zero (stop).

    The page has no press-and-hold event: a slider moved, or a pad button pressed, gives the
    command again; when the user stops giving it, the arm stops (released = stop).
    """

    def __init__(self, size: int, hold: float):
        """Hold commands of ``size`` numbers for ``hold`` [s]."""
        self.size = size
        self.hold = float(hold)
        self.values = np.zeros(size)
        self.until = -np.inf
        self.sent_zero = True

    def give(self, values: Sequence[float], now: float) -> None:
        """Take a command (finite numbers) at ``now`` [s]; refuse one that is not finite."""
        values = as_finite_array(values, (self.size,), 'jog command')
        self.values = values
        self.until = now + self.hold if np.any(values) else -np.inf
        self.sent_zero = False

    def release(self) -> None:
        """Stop at once."""
        self.values = np.zeros(self.size)
        self.until = -np.inf

    def due(self, now: float) -> Optional[np.ndarray]:
        """Return the command to send at ``now``: the held one, one zero after it, then None."""
        if now < self.until:
            return self.values
        if not self.sent_zero:
            self.sent_zero = True
            self.values = np.zeros(self.size)
            return self.values
        return None
