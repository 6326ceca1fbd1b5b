"""
A program planned whole before it moves: every move solved, checked and timed, or refused.

``plan_program`` walks the run order from the arm's joint positions: each move is solved by the
planner's core (``planning.planner_core``: a ptp to the point's joints or the pose's nearest IK
solution inside the limits, a lin along its straight line, a circ along its arc, IK within the
limits on every waypoint, the swept motion collision-checked), consecutive moves with a blend
become one ``Motion`` (``blend_zone``: the waypoints within the radius of the corner give way
to the joint-space line across it, rounded by the time-optimal path), and each motion is timed
time-optimally with the joint limits at the program's speed fraction and the tool speeds of
its lin and circ moves (``tool_timing``). The first step that cannot run refuses the whole
program (``ProgramError`` with its line, its run index and the planner's reason): nothing is
sent before the plan is whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mover6_control.collision.checker import CollisionChecker
from mover6_control.errors import error_code, InvalidInputError, REASONS, UnreachableError
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.motion.timing.path_timing import PathTrajectory
from mover6_control.planning.planner_core import (closest_solution, collision_refusal,
                                                  make_checker, plan_path_goal,
                                                  plan_pose_goal, PlannerSettings)
from mover6_control.programs.limits import CartesianLimits, JointLimits
from mover6_control.programs.program_error import PROGRAM_CODES, ProgramError
from mover6_control.programs.program_file import check_blends, Program
from mover6_control.programs.steps import GripperStep, Move, SpeedStep, WaitStep
from mover6_control.programs.tool_timing import timed_path
import numpy as np

# The planner settings of a program's lin and circ moves: a waypoint every 5 mm and 0.05 rad
# of the tool path.
PROGRAM_PLANNER = PlannerSettings(max_step=0.005, max_angle_step=0.05)


@dataclass(frozen=True)
class PlanSettings:
    """How a program is planned: the planner's settings, the limits and the path's rounding."""

    planner: PlannerSettings = PROGRAM_PLANNER
    joint: JointLimits | None = None          # None: the arm's (``JointLimits.of``)
    cartesian: CartesianLimits | None = None  # None: Pilz's (``CartesianLimits.load``)
    ptp_step: float = 0.05        # [rad] largest joint step between a ptp's waypoints
    max_deviation: float = 1e-3   # [rad] the time-optimal path's corner arcs
    zone_tolerance: float = 1e-3  # [m] a blend may pass its radius by this (the rounding)


@dataclass(frozen=True)
class MovePlan:
    """One move solved: its run index, step, joint waypoints (k, n) and tool positions (k, 3)."""

    index: int
    step: Move
    q: np.ndarray
    positions: np.ndarray


@dataclass(frozen=True)
class Corner:
    """A blend corner: the corner point (3,) [m], its radius [m] and the move it ends."""

    point: np.ndarray
    radius: float
    index: int


@dataclass(frozen=True, eq=False)
class Motion:
    """
    One continuous motion, rest to rest: one move, or several joined by blends.

    ``q`` (m, n) are the waypoints sent (after the blend zones), ``owner`` (m,) the run index of
    the move each waypoint belongs to, ``trajectory`` their time-optimal timing, ``moves`` the
    solved moves (the nominal paths), ``fraction`` the speed fraction it was timed at.
    """

    moves: tuple
    q: np.ndarray
    owner: np.ndarray
    corners: tuple
    trajectory: PathTrajectory
    fraction: float

    @property
    def indices(self) -> tuple:
        """Return the run indices of its moves."""
        return tuple(m.index for m in self.moves)

    @property
    def duration(self) -> float:
        """Return its duration [s]."""
        return float(self.trajectory.duration)

    def end_times(self) -> np.ndarray:
        """Return the time [s] each of its moves ends (its last waypoint passed), (k,)."""
        times = self.trajectory.waypoint_times
        keep = np.concatenate([[True], np.linalg.norm(np.diff(self.q, axis=0), axis=1) > 1e-12])
        owner = self.owner[keep]
        return np.array([times[np.flatnonzero(owner == i)[-1]] for i in self.indices])


@dataclass(frozen=True)
class Action:
    """A step of the run that does not move the arm: its run index and step."""

    index: int
    step: GripperStep | WaitStep | SpeedStep


@dataclass(frozen=True, eq=False)
class PlannedProgram:
    """A program planned whole: its motions and actions in run order, and where it ends."""

    program: Program
    items: tuple                    # Motion and Action in run order
    q_start: np.ndarray
    q_end: np.ndarray
    arm: ArmModel = field(repr=False, default=None)

    def motions(self) -> list[Motion]:
        """Return the motions."""
        return [m for m in self.items if isinstance(m, Motion)]

    @property
    def motion_time(self) -> float:
        """Return the time [s] the arm moves (the waits and the gripper not counted)."""
        return float(sum(m.duration for m in self.motions()))


def _refusal(program: Program, index: int, err: Exception) -> ProgramError:
    step = program.run[index].step
    code = err.code if isinstance(err, ProgramError) else error_code(err)
    if code not in REASONS and code not in PROGRAM_CODES:
        code = 'unreachable'
    reason = err.reason if isinstance(err, ProgramError) else str(err)
    return ProgramError(program.path, step.line, f'step {index + 1} "{step.name}" cannot run: '
                        f'{reason}', code, index)


def _ptp(arm, q, step, settings, checker):
    if step.target.joints is not None:
        q_goal = np.array(step.target.joints)
    else:
        q_goal = closest_solution(arm, step.target.T, q, 'target')
    n = max(2, int(np.ceil(np.abs(q_goal - q).max() / settings.ptp_step)) + 1)
    path = q + np.linspace(0.0, 1.0, n)[:, None] * (q_goal - q)
    if checker is not None:
        err = collision_refusal(checker, path, 'the move')
        if err is not None:
            raise err
    return path


def solve_move(arm: ArmModel, q: np.ndarray, step: Move, settings: PlanSettings,
               checker: CollisionChecker | None) -> np.ndarray:
    """Return the joint waypoints (k, n) of ``step`` from ``q``, the first row ``q``."""
    if step.kind == 'ptp':
        return _ptp(arm, q, step, settings, checker)
    if step.kind == 'lin':
        plan = plan_pose_goal(arm, q, step.target.T, 'linear', settings.planner, checker)
    else:
        plan = plan_path_goal(arm, q, [step.via.T], step.target.T, 'arc', settings.planner,
                              checker)
    return plan.q


def _crossing(q, d, radius, inside, outside):
    """Return the joint positions where the tool crosses ``radius``, between two waypoints."""
    f = (d[outside] - radius) / max(d[outside] - d[inside], 1e-12)
    return q[outside] + f * (q[inside] - q[outside])


def trimmed(move: MovePlan, before: Corner | None, after: Corner | None) -> np.ndarray:
    """
    Return the waypoints of ``move`` outside the blend zones at its start and its end.

    A zone is the ball of a corner's radius around its point: the waypoints whose tool
    position lies inside it are dropped from that end, and the end is the point where the tool
    crosses the radius (joint positions interpolated between the waypoints either side).
    Raises ``InvalidInputError`` when the two zones leave nothing of it.
    """
    q, pos = move.q, move.positions
    lo, hi = 0, len(q) - 1
    head = tail = None
    if before is not None and before.radius > 0.0:
        d = np.linalg.norm(pos - before.point, axis=1)
        out = np.flatnonzero(d > before.radius)
        if out.size == 0:
            raise InvalidInputError('the blend zone before it covers the whole move')
        lo = int(out[0])
        head = _crossing(q, d, before.radius, lo - 1, lo) if lo > 0 else None
    if after is not None and after.radius > 0.0:
        d = np.linalg.norm(pos - after.point, axis=1)
        out = np.flatnonzero(d > after.radius)
        if out.size == 0:
            raise InvalidInputError('its blend zone covers the whole move')
        hi = int(out[-1])
        tail = _crossing(q, d, after.radius, hi + 1, hi) if hi < len(q) - 1 else None
    if lo > hi:
        raise InvalidInputError('the blend zones at its start and its end overlap: make the '
                                'radii smaller')
    parts = [q[lo:hi + 1]]
    if head is not None:
        parts.insert(0, head[None])
    if tail is not None:
        parts.append(tail[None])
    return np.vstack(parts)


def blend_zone(moves: list) -> tuple[np.ndarray, np.ndarray, tuple]:
    """
    Return the waypoints (m, n), their owners (m,) and the ``Corner``s of blended ``moves``.

    Every move but the last ends in a corner with a radius: the waypoints within it are cut
    from the end of the move into it and the start of the move out of it (``trimmed``), and
    the joint-space line between the two crossings joins them. The first row is the first
    move's start.
    """
    corners = tuple(Corner(m.positions[-1], m.step.blend, m.index) for m in moves[:-1])
    rows, owners = [], []
    for i, move in enumerate(moves):
        before = corners[i - 1] if i > 0 else None
        after = corners[i] if i < len(corners) else None
        try:
            piece = trimmed(move, before, after)
        except InvalidInputError as err:
            raise ProgramError('', move.step.line, str(err), 'blend_radius', move.index)
        rows.append(piece)
        owners.append(np.full(len(piece), move.index))
    return np.vstack(rows), np.concatenate(owners), corners


def zone_excess(arm: ArmModel, q: np.ndarray, owner: np.ndarray, corners: tuple,
                samples: int = 20) -> list:
    """
    Return, per corner, the tool's largest distance [m] from it while crossing its zone.

    The crossing is the joint-space line between the last waypoint of the move into the corner
    and the first of the move out of it, sampled ``samples`` times.
    """
    out = []
    for corner in corners:
        last = int(np.flatnonzero(owner == corner.index)[-1])
        s = np.linspace(0.0, 1.0, samples)[:, None]
        chord = q[last] + s * (q[last + 1] - q[last])
        d = np.linalg.norm(fk_batch(arm, chord)[:, :3, 3] - corner.point, axis=1)
        out.append(float(d.max()))
    return out


def _motion(arm, program, moves, fraction, settings, checker):
    limits = settings.joint.scaled(fraction)
    if len(moves) > 1:
        try:
            q, owner, corners = blend_zone(moves)
        except ProgramError as err:
            raise _refusal(program, err.step, err) from None
        if checker is not None:
            err = collision_refusal(checker, q, 'the blended motion')
            if err is not None:
                raise _refusal(program, moves[0].index, err) from None
        for corner, far in zip(corners, zone_excess(arm, q, owner, corners)):
            if far > corner.radius + settings.zone_tolerance:
                raise _refusal(program, corner.index, ProgramError(
                    program.path, 0, f'its blend strays {far * 1e3:.1f} mm from the corner, '
                    f'beyond its radius {corner.radius * 1e3:.1f} mm: make the radius smaller '
                    'or the moves around it straighter', 'blend_radius')) from None
    else:
        q, owner, corners = moves[0].q, np.full(len(moves[0].q), moves[0].index), ()
    by_index = {m.index: m.step for m in moves}
    speed = np.array([by_index[i].speed if by_index[i].kind != 'ptp' else np.inf
                      for i in owner])
    rot = np.array([by_index[i].rot_speed if by_index[i].kind != 'ptp' else np.inf
                    for i in owner])
    try:
        trajectory = timed_path(arm, q, speed, rot, limits.velocity, limits.acceleration,
                                settings.max_deviation)
    except (UnreachableError, InvalidInputError) as err:
        raise _refusal(program, moves[0].index, err) from None
    return Motion(tuple(moves), q, owner, corners, trajectory, fraction)


def plan_program(arm: ArmModel, program: Program, q_start: np.ndarray,
                 settings: PlanSettings = PlanSettings(),
                 checker: CollisionChecker | None = None) -> PlannedProgram:
    """
    Return the ``PlannedProgram`` of ``program`` from joint positions ``q_start`` (n,).

    Raises ``ProgramError`` for the first step that cannot run (its line, its run index, the
    planner's reason as the code); nothing of the plan is returned then.
    """
    q = arm.check_q(q_start, 'start joint positions')
    if not arm.within_limits(q):
        raise ProgramError(program.path, 0, 'the arm is outside the joint limits: '
                           + '; '.join(arm.limit_violations(q)), 'joint_limits')
    if settings.joint is None:
        settings = PlanSettings(**{**settings.__dict__, 'joint': JointLimits.of(arm)})
    if checker is None:
        checker = make_checker(arm, settings.planner)
    check_blends(program.path, list(program.run), fk(arm, q)[:3, 3])
    items, group, fraction = [], [], 1.0
    for run in program.run:
        step = run.step
        if isinstance(step, Move):
            try:
                path = solve_move(arm, q, step, settings, checker)
            except (UnreachableError, InvalidInputError) as err:
                raise _refusal(program, run.index, err) from None
            group.append(MovePlan(run.index, step, path, fk_batch(arm, path)[:, :3, 3]))
            q = path[-1]
            if step.blend == 0.0:
                items.append(_motion(arm, program, group, fraction, settings, checker))
                group = []
            continue
        if isinstance(step, SpeedStep):
            fraction = step.fraction
        items.append(Action(run.index, step))
    return PlannedProgram(program, tuple(items), np.array(q_start, dtype=float), q, arm)
