"""
Goal planning: from the current configuration and a goal to joint waypoints (n, 6).

The planner node is a thin shell around ``plan_pose_goal`` and ``plan_path_goal``: it converts
messages, calls these, and publishes the result or the refusal. Everything here is ROS-free and
clock-free.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from mover6_control.collision.checker import CollisionChecker, CollisionSettings
from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.kinematics.forward import condition_number, fk, fk_batch, jacobian
from mover6_control.kinematics.ik_closed_form import ik_closed_form, pose_errors_batch
from mover6_control.kinematics.path_ik import solve_path
from mover6_control.kinematics.reachability import check_pose
from mover6_control.kinematics.rotations import pose_error
from mover6_control.motion import paths
from mover6_control.parameters import PATH_MOTIONS, PLANNER, POSE_MOTIONS   # defaults, shapes
from mover6_control.values import poses_of, ToolPose
import numpy as np

if TYPE_CHECKING:
    from mover6_control.kinematics.arm import ArmModel

# Path shapes that take exactly one via pose ('joint': /path_goal/joint, ``planning.via_joint``).
ONE_VIA_SHAPES = ('arc', 'parabolic', 'joint')
# Most via poses a path goal may have. Each is checked on its own (IK, reachability: milliseconds
# each) before the path is solved through them all: 10,000 held the planner for half a minute.
MAX_VIA_POSES = 100


@dataclass(frozen=True)
class PlannerSettings:
    """
    Settings of a plan; defaults are the planner node's parameter defaults.

    ``max_step`` [m] and ``max_angle_step`` [rad] sample the Cartesian path by step when > 0;
    otherwise ``n_waypoints`` poses are used. ``collision`` says what the collision check of
    every plan checks (``collision.enabled`` False: nothing).
    """

    n_waypoints: int = PLANNER['n_waypoints'].default
    max_step: float = PLANNER['max_step'].default
    max_angle_step: float = PLANNER['max_angle_step'].default
    peak_height: float = PLANNER['peak_height'].default
    max_joint_step: float = PLANNER['max_joint_step'].default
    max_condition: float = PLANNER['max_condition'].default
    position_tolerance: float = PLANNER['position_tolerance'].default
    orientation_tolerance: float = PLANNER['orientation_tolerance'].default
    velocity_scale: float = 1.0
    collision: CollisionSettings = CollisionSettings()

    def __post_init__(self):
        """Reject settings that cannot make a plan."""
        if int(self.n_waypoints) < 2:
            raise InvalidInputError(f'n_waypoints must be >= 2, got {self.n_waypoints}')
        for name in ('max_step', 'max_angle_step'):
            if not np.isfinite(getattr(self, name)) or getattr(self, name) < 0.0:
                raise InvalidInputError(f'{name} must be >= 0, got {getattr(self, name)}')
        for name in ('max_joint_step', 'max_condition', 'position_tolerance',
                     'orientation_tolerance', 'velocity_scale'):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise InvalidInputError(f'{name} must be > 0, got {value}')

    def sampling(self) -> dict[str, float | int | None]:
        """Return the keyword arguments that sample a path (by count or by step)."""
        if self.max_step > 0.0 or self.max_angle_step > 0.0:
            return {'max_step': self.max_step or None,
                    'max_angle_step': self.max_angle_step or None}
        return {'n': int(self.n_waypoints)}


@dataclass(frozen=True)
class JointPlan:
    """A planned motion: joint waypoints (n, 6) [rad] and the figures reported with it."""

    motion: str
    q: np.ndarray             # (n, 6) [rad]
    poses: np.ndarray         # (n, 4, 4) the intended tool poses (FK of q for joint moves)
    path_length: float        # [m] of the intended tool path
    predicted_duration: float  # [s] rough estimate; the node announces the controller's timing
    final_position_error: float     # [m] FK of the last waypoint against the goal
    final_orientation_error: float  # [rad]

    @property
    def n_waypoints(self) -> int:
        """Return the number of waypoints."""
        return int(self.q.shape[0])


def check_path_shape(motion: str, n_vias: int) -> None:
    """
    Raise ``InvalidInputError`` when a path goal of shape ``motion`` cannot have ``n_vias`` vias.

    The cheap check of a path goal, made before any of its poses is converted or solved: the
    shape is known ('joint' included), the shapes of one via pose get exactly one, and no path
    has more than ``MAX_VIA_POSES``.
    """
    if motion not in PATH_MOTIONS + ('joint',):
        raise InvalidInputError(f'unknown path motion "{motion}", expected one of {PATH_MOTIONS}')
    if motion in ONE_VIA_SHAPES and n_vias != 1:
        raise InvalidInputError(f'{motion} needs exactly one via pose, got {n_vias}')
    if n_vias > MAX_VIA_POSES:
        raise InvalidInputError(f'a path goal has at most {MAX_VIA_POSES} via poses, got {n_vias}')


def polyline_length(points: np.ndarray) -> float:
    """Return the length [m] of a polyline (n, 3)."""
    points = np.asarray(points, dtype=float)
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def travel_time(arm: ArmModel, q: np.ndarray, velocity_scale: float = 1.0) -> float:
    """
    Return the time [s] to visit waypoints (n, 6), each segment at the slowest joint's pace.

    A speed-limit-only measure to compare candidate plans (the wrist turns out of a singular
    start); the planner node announces the controller's own timing instead.
    """
    steps = np.abs(np.diff(np.asarray(q, dtype=float), axis=0))
    return float((steps / (arm.velocity_limits * velocity_scale)).max(axis=1).sum())


def _finish(arm, motion, q, poses, T_goal, settings):
    q = np.asarray(q, dtype=float)
    T_end = fk(arm, q[-1])
    pos_err, rot_err = pose_error(T_end, T_goal)
    if pos_err > settings.position_tolerance or rot_err > settings.orientation_tolerance:
        raise UnreachableError(
            f'the last waypoint misses the goal by {pos_err * 1e3:.2f} mm and {rot_err:.4f} rad '
            f'(tolerance {settings.position_tolerance * 1e3:.2f} mm, '
            f'{settings.orientation_tolerance:.4f} rad)',
            reason='out_of_reach',
            details={'waypoint': len(q) - 1, 'position_error': pos_err,
                     'orientation_error': rot_err, 'closest_q': q[-1], 'closest_pose': T_end})
    return JointPlan(motion=motion, q=q, poses=np.asarray(poses),
                     path_length=polyline_length(np.asarray(poses)[:, :3, 3]),
                     predicted_duration=travel_time(arm, q, settings.velocity_scale),
                     final_position_error=pos_err, final_orientation_error=rot_err)


def _solve_path(arm, path, q_start, settings):
    """
    Return (q, poses) of ``path`` (a ``paths.PosePath``) after its first pose from ``q_start``.

    A joint step too large between two waypoints is followed along the path's own curve, and
    the waypoints found on the way are inserted (``path_ik.solve_path``'s ``pose_between``).
    """
    sol = solve_path(arm, path.poses[1:], q_start, max_joint_step=settings.max_joint_step,
                     max_condition=settings.max_condition,
                     position_tol=settings.position_tolerance,
                     orientation_tol=settings.orientation_tolerance,
                     pose_between=lambda k, s: path.between(k + 1, s))
    return sol.q, sol.poses


def _wrist_turns(arm, q_current, T_next, settings):
    """
    Return the possible starts (k, n) of a path from ``q_current``: itself, or wrist turns.

    At a singular start, such as the Mover6's home (q5 = 0: axes 4 and 6 aligned), the pose
    does not fix q4 and q6 apart, and the path's next pose can need a large wrist turn. That
    turn is made first, along the Jacobian's null space (at home: q4 and q6 in opposite senses
    about their aligned axes), which leaves the tool pose unchanged, as far as it brings the
    configuration towards one of the next pose's solutions; in steps within ``max_joint_step``,
    accepted only when FK along it stays within the tolerances of the start pose. The next
    pose's wrist branches give one turn each (smallest first): which one the path can continue
    on, and at what cost, only the whole path tells (``_solve``).
    """
    no_turn = [q_current[None]]
    if condition_number(arm, q_current) <= settings.max_condition:
        return no_turn
    try:
        solutions = ik_closed_form(arm, ToolPose.computed(T_next), within_limits=True,
                                   q_ref=q_current)     # a pose of the path: computed
    except InvalidInputError:
        return no_turn   # no closed form for this arm: the path solver deals with it
    v = np.linalg.svd(jacobian(arm, q_current))[2][-1]
    starts = []
    for q1 in solutions[np.argsort(np.abs(solutions - q_current).max(axis=1))]:
        if np.abs(q1 - q_current).max() <= settings.max_joint_step:
            starts.append(q_current[None])
            continue
        q_turned = q_current + float(v @ (q1 - q_current)) * v
        n_bridge = int(np.ceil(np.abs(q_turned - q_current).max() / settings.max_joint_step)) + 1
        fine = q_current + np.linspace(0.0, 1.0, 20 * n_bridge)[:, None] * (q_turned - q_current)
        pos, rot = pose_errors_batch(fk(arm, q_current), fk_batch(arm, fine))
        if (pos.max() <= settings.position_tolerance
                and rot.max() <= settings.orientation_tolerance
                and arm.within_limits(q_turned)):
            starts.append(q_current + np.linspace(0.0, 1.0, n_bridge)[:, None]
                          * (q_turned - q_current))
    # Without a turn that can be made in place, the path solver reports the jump.
    unique = []
    for start in starts or no_turn:
        if not any(len(u) == len(start) and np.allclose(u, start) for u in unique):
            unique.append(start)
    return unique


# Refusals of the way, not of the goal (checked before, ``check_goal``).
PATH_ONLY_REASONS = ('discontinuity', 'joint_limits')


def _solve(arm, path, q_current, settings):
    """
    Return (q, poses) for ``path`` from ``q_current``, leaving a singular start if needed.

    ``path`` is a ``paths.PosePath``; the rows of the result are its poses, the wrist turn's
    (at the first pose) and any inserted on the way. path.poses[0] is the current pose and
    ``q_current`` its solution: the path starts there exactly
    (solving it again could pick the other wrist branch, or trip over sensor noise). A wrist
    turn out of a singular start (``_wrist_turns``) comes first when the next pose needs one;
    of the turns whose path can be followed, the one with the shortest motion (turn and path,
    ``travel_time``) is taken. A refusal is the one of the smallest turn.
    """
    best, best_time, refusal = None, np.inf, None
    for start in _wrist_turns(arm, q_current, path.poses[1], settings):
        try:
            q, poses = _solve_path(arm, path, start[-1], settings)
        except UnreachableError as err:
            refusal = refusal or err
            continue
        q = np.vstack([start, q])
        duration = travel_time(arm, q, settings.velocity_scale)
        if duration < best_time:
            best_time = duration
            best = q, np.concatenate([np.repeat(path.poses[:1], len(start), axis=0), poses])
    if best is not None:
        return best
    details = dict(refusal.details, waypoint=refusal.details.get('waypoint', -1) + 1)
    message = str(refusal)
    if refusal.reason in PATH_ONLY_REASONS:    # the goal itself passed check_goal: say so
        message += ('; the goal itself is reachable inside the limits: a joint move '
                    '(/pose_goal/joint, goal --motion joint) gets there')
    raise UnreachableError(message, reason=refusal.reason, details=details) from None


def collision_refusal(checker: CollisionChecker, q: np.ndarray,
                      what: str = 'the path') -> UnreachableError | None:
    """
    Return the ``UnreachableError`` (reason 'collision') of waypoints ``q`` (n, 6), or None.

    The whole swept motion is checked: the straight joint-space lines between the waypoints,
    sampled every ``checker.settings.max_joint_step``. ``q[0]`` is where the arm is: a contact
    it is in already may get shallower but no deeper (``escape``), so it can be moved out. The
    message names the shapes, the depth and where: "link6 tool is 14 mm into the table margin
    at 62 % of the path".
    """
    check = checker.check_path(q, escape=True)
    if check.free:
        return None
    first = check.first
    text = checker.message(check).replace('of the path', f'of {what}')
    return UnreachableError(
        f'{text} (between waypoints {first.waypoint} and {first.waypoint + 1}); move the goal '
        'or a via pose away, or change tool_size, table_margin or keep_out_boxes',
        reason='collision',
        details={'waypoint': first.waypoint, 'fraction': first.fraction,
                 'shapes': ' and '.join(first.shapes), 'depth': first.depth,
                 'closest_q': first.q, 'clearance': dict(check.clearance)})


def make_checker(arm: ArmModel, settings: PlannerSettings) -> CollisionChecker | None:
    """Return the collision checker of ``settings`` (None when the check is off)."""
    if not settings.collision.enabled:
        return None
    return CollisionChecker(arm, settings.collision)


def check_goal_collision(arm: ArmModel, T_goal: np.ndarray, q_current: np.ndarray,
                         checker: CollisionChecker | None) -> None:
    """
    Raise ``UnreachableError`` (reason 'collision') when every way to stand at ``T_goal`` collides.

    Checked before any path, so a goal in the table is refused for the table rather than for
    whatever the path meets first. Arms without a closed form are left to the path check.
    """
    if checker is None:
        return
    try:
        solutions = ik_closed_form(arm, T_goal, within_limits=True, q_ref=q_current)
    except InvalidInputError:
        return
    if len(solutions) == 0:
        return
    verdicts = [checker.check_configurations(q[None]) for q in solutions]
    if any(v.free for v in verdicts):
        return
    first = verdicts[0].first
    raise UnreachableError(
        f'the goal collides: {first.describe(checker.geometry.table_margin)}'.replace(
            ' at 0 % of the path', '') + ' at the goal, in every joint configuration that '
        'reaches it', reason='collision',
        details={'waypoint': -1, 'fraction': 1.0, 'shapes': ' and '.join(first.shapes),
                 'depth': first.depth, 'closest_q': first.q})


def check_plan_collision(plan: JointPlan, checker: CollisionChecker | None) -> JointPlan:
    """Return ``plan`` when its swept motion is free (or ``checker`` is None), else raise."""
    if checker is None:
        return plan
    err = collision_refusal(checker, plan.q)
    if err is not None:
        raise err
    return plan


def closest_solution(arm: ArmModel, T: np.ndarray, q_ref: np.ndarray, what: str) -> np.ndarray:
    """
    Return the IK solution (6,) of ``T`` inside the limits nearest ``q_ref`` (largest joint step).

    Raises ``UnreachableError`` as a joint move does: ``joint_limits`` with the closest
    configuration outside them, or ``out_of_reach``.
    """
    solutions = ik_closed_form(arm, T, within_limits=True)
    if len(solutions) == 0:
        all_solutions = ik_closed_form(arm, T, within_limits=False)
        if len(all_solutions) > 0:
            best = all_solutions[np.argmin(np.abs(all_solutions - q_ref).max(axis=1))]
            raise UnreachableError(
                f'the {what} is reachable only outside the joint limits: '
                + '; '.join(arm.limit_violations(best)),
                reason='joint_limits',
                details={'waypoint': 0, 'position_error': 0.0, 'orientation_error': 0.0,
                         'closest_q': best, 'closest_pose': fk(arm, best)})
        raise UnreachableError(f'no inverse kinematics solution: the {what} is out of reach',
                               reason='out_of_reach', details={'waypoint': 0})
    return solutions[np.argmin(np.abs(solutions - q_ref).max(axis=1))]


def plan_joint_move(arm: ArmModel, q_current: np.ndarray, T_goal: np.ndarray,
                    settings: PlannerSettings):
    """Plan a straight line in joint space to the IK solution closest to ``q_current``."""
    q_goal = closest_solution(arm, T_goal, q_current, 'goal')
    n = max(2, int(np.ceil(np.abs(q_goal - q_current).max() / settings.max_joint_step)) + 1,
            int(settings.n_waypoints))
    s = np.linspace(0.0, 1.0, n)[:, None]
    q = q_current + s * (q_goal - q_current)
    return _finish(arm, 'joint', q, fk_batch(arm, q), T_goal, settings)


def check_goal(arm: ArmModel, T_goal: np.ndarray, q_current: np.ndarray,
               settings: PlannerSettings, what: str = 'goal', singular_ok: bool = False) -> None:
    """
    Raise ``UnreachableError`` when ``T_goal`` itself cannot be reached.

    Checked before any path, so an impossible goal is refused for what it is (out of reach,
    joint limits, singular) rather than for the first path waypoint that fails on the way.
    ``singular_ok`` accepts a singular goal (joint moves: no Cartesian rate to blow up there).
    """
    verdict = check_pose(arm, T_goal, q_current,
                         max_condition=None if singular_ok else settings.max_condition,
                         position_tol=settings.position_tolerance,
                         orientation_tol=settings.orientation_tolerance)
    if not verdict.reachable:
        details = dict(verdict.details, position_error=verdict.position_error,
                       orientation_error=verdict.orientation_error,
                       closest_pose=verdict.closest_pose, waypoint=verdict.waypoint)
        raise UnreachableError(f'the {what} is not reachable: {verdict.message}',
                               reason=verdict.reason, details=details)


def plan_pose_goal(arm: ArmModel, q_current: np.ndarray, T_goal: np.ndarray,
                   motion: str = 'linear', settings: PlannerSettings = PlannerSettings(),
                   checker: CollisionChecker | None = None):
    """
    Plan a move of the tool from FK(``q_current``) to ``T_goal`` (4, 4).

    Every plan's swept motion is checked for collisions (``settings.collision``; ``checker``
    a prebuilt ``CollisionChecker`` of those settings, else one is made), refused with reason
    'collision' before anything is returned.

    ``motion`` is 'linear' (straight line, SLERPed orientation), 'parabolic' (through a peak
    ``settings.peak_height`` [m] above the mid-point, along base z) or 'joint' (straight in joint
    space). Raises ``UnreachableError`` (with ``reason`` and ``details``) or
    ``InvalidInputError``.
    """
    q_current = arm.check_q(q_current, 'current joint positions')
    T_goal = ToolPose.of(T_goal, 'goal pose')     # a ToolPose (a message's) passes unchecked
    if motion not in POSE_MOTIONS:
        raise InvalidInputError(f'unknown motion "{motion}", expected one of {POSE_MOTIONS}')
    T_start = ToolPose.computed(fk(arm, q_current))
    pos_err, rot_err = pose_error(T_start, T_goal)
    if pos_err < 1e-6 and rot_err < 1e-6:
        # Already there: a two-row hold lets the controller report arrival at once.
        return _finish(arm, motion, np.stack([q_current, q_current]),
                       np.stack([T_start, T_start]), T_goal, settings)
    check_goal(arm, T_goal, q_current, settings, singular_ok=motion == 'joint')
    checker = checker or make_checker(arm, settings)
    check_goal_collision(arm, T_goal, q_current, checker)
    if motion == 'joint':
        return check_plan_collision(plan_joint_move(arm, q_current, T_goal, settings), checker)
    if motion == 'linear':
        path = paths.linear_curve(T_start, T_goal, **settings.sampling())
    else:
        path = paths.parabolic_curve(T_start, T_goal, settings.peak_height,
                                     **settings.sampling())
    q, poses = _solve(arm, path, q_current, settings)
    return check_plan_collision(_finish(arm, motion, q, poses, T_goal, settings), checker)


def plan_path_goal(arm: ArmModel, q_current: np.ndarray, T_vias: np.ndarray,
                   T_goal: np.ndarray, motion: str = 'spline',
                   settings: PlannerSettings = PlannerSettings(),
                   checker: CollisionChecker | None = None):
    """
    Plan a move through via poses (k, 4, 4) to ``T_goal``.

    ``motion`` is 'spline', 'arc' (one via pose) or 'parabolic' (one via pose: the peak, the
    Mover6 report's eq. 12; its position is used).

    Raises ``UnreachableError`` or ``InvalidInputError`` as ``plan_pose_goal`` does, and
    checks for collisions as it does. The cheap checks come first (``check_path_shape``: the
    via count), then each pose's form, then each pose's reachability.
    """
    if motion not in PATH_MOTIONS:
        raise InvalidInputError(f'unknown path motion "{motion}", expected one of {PATH_MOTIONS}')
    if not isinstance(T_vias, (list, tuple)):
        T_vias = np.asarray(T_vias, dtype=float).reshape(-1, 4, 4)
    check_path_shape(motion, len(T_vias))     # cheap checks first: count, then each pose's form
    q_current = arm.check_q(q_current, 'current joint positions')
    T_goal = ToolPose.of(T_goal, 'goal pose')     # ToolPose values (a message's) pass unchecked
    T_vias = poses_of(T_vias, 'via pose')
    for i, T in enumerate(T_vias):
        check_goal(arm, T, q_current, settings, what=f'via pose {i}')
    check_goal(arm, T_goal, q_current, settings)
    checker = checker or make_checker(arm, settings)
    check_goal_collision(arm, T_goal, q_current, checker)
    T_start = ToolPose.computed(fk(arm, q_current))
    if motion in ('arc', 'parabolic'):
        if motion == 'arc':
            path = paths.arc_curve(T_start, T_vias[0], T_goal, **settings.sampling())
        else:
            path = paths.parabolic_curve_through(T_start, T_vias[0][:3, 3], T_goal,
                                                 **settings.sampling())
    else:
        if len(T_vias) == 0:
            path = paths.linear_curve(T_start, T_goal, **settings.sampling())
        else:
            path = paths.spline_curve(T_start, T_vias, T_goal, **settings.sampling())
    q, poses = _solve(arm, path, q_current, settings)
    return check_plan_collision(_finish(arm, motion, q, poses, T_goal, settings), checker)
