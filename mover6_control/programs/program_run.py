"""
What running a planned program needs apart from ROS: its motions as timed points, a plan's text.

``timed_points`` samples a ``Motion``'s time-optimal trajectory into the points of a
joint trajectory goal (time from start, positions, velocities): the controller follows them at
their times (cubic Hermite between them), so the arm runs the planned path and timing (scaled by
the controller's speed scaling). Points sit at every time the motion's acceleration may jump
(``break_times``), so the cubic pieces stay on it and within the limits; the accelerations at
such a time are one-sided and are not sent. ``plan_lines`` is the plan as a user reads it: one
line per motion
and action. ``teach_refusal`` says why a point cannot be taught from a joint state reading
(stale, or the arm moving), or None.
"""

from __future__ import annotations

from dataclasses import dataclass

from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk
from mover6_control.programs.program_error import ProgramError
from mover6_control.programs.program_plan import Motion, PlannedProgram
import numpy as np

# [s] the time between the points of a motion's goal.
POINT_PERIOD = 0.05
# A point is taught only from joint states younger than this [s] and with every joint slower
# than TEACH_SPEED [rad/s].
TEACH_MAX_AGE = 0.5
TEACH_SPEED = 1e-3
# [s] the closest two points of a motion's goal.
MIN_GAP = 1e-3


@dataclass(frozen=True)
class TimedPoints:
    """A motion as goal points: times (k,) [s], positions and velocities (k, n)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray


def break_times(trajectory) -> np.ndarray:
    """
    Return the times [s] where a motion's acceleration may jump: its timing's grid, its path's.

    The time-optimal timing holds the path acceleration constant between its grid points, and
    the path's curvature changes where a line meets a blend arc: between such times the motion
    is smooth, so a point at each keeps the controller's interpolation on the planned motion.
    """
    timing, factor = trajectory.timing, 1.0
    if not hasattr(timing, 't_grid') and hasattr(timing, 'factor'):
        timing, factor = timing.base, float(timing.factor)
    grid = np.asarray(getattr(timing, 't_grid', np.empty(0)), dtype=float) * factor
    ends = np.asarray(trajectory.timing.time_at(np.asarray(trajectory.path.starts)), dtype=float)
    return np.concatenate([grid, ends])


def timed_points(motion: Motion, period: float = POINT_PERIOD,
                 min_gap: float = MIN_GAP) -> TimedPoints:
    """
    Return ``motion`` as points every ``period`` [s] and at its ``break_times``, resting at last.

    Points closer than ``min_gap`` [s] to the one before are left out; the first point is after
    time 0 (a first point at 0 would be the start state), the last at the motion's end.
    """
    duration = motion.duration
    n = max(1, int(np.ceil(duration / period)))
    t = np.concatenate([np.linspace(duration / n, duration, n), break_times(motion.trajectory)])
    t = np.unique(t[(t > min_gap) & (t < duration - min_gap)])
    keep = [0] if t.size else []
    for i in range(1, t.size):
        if t[i] - t[keep[-1]] >= min_gap:
            keep.append(i)
    t = np.append(t[keep], duration)
    q, qd, _ = motion.trajectory.sample(t)
    qd = np.array(qd, dtype=float)
    qd[-1] = 0.0
    return TimedPoints(t, np.array(q, dtype=float), qd)


def stretched(points: TimedPoints, factor: float) -> TimedPoints:
    """Return the same points ``factor`` >= 1 times slower: the same path, rates divided."""
    return TimedPoints(points.t * factor, points.q, points.qd / factor)


def end_of(motion: Motion) -> np.ndarray:
    """Return the joint positions (n,) [rad] a motion ends at."""
    return np.array(motion.trajectory.sample(np.array([motion.duration]))[0][-1], dtype=float)


def plan_lines(plan: PlannedProgram) -> list[str]:
    """Return the plan as lines: each motion (its steps, duration) and action, and the total."""
    steps = plan.program.run
    lines = [f'program "{plan.program.name}" ({plan.program.path}): {len(steps)} steps, '
             f'{len(plan.motions())} motions, {plan.motion_time:.2f} s of motion']
    for item in plan.items:
        if isinstance(item, Motion):
            names = ' > '.join(f'{i + 1} {steps[i].step.name}' for i in item.indices)
            lines.append(f'  motion {item.duration:6.2f} s  {names}'
                         + (f' (speed {item.fraction:g})' if item.fraction != 1.0 else ''))
        else:
            lines.append(f'  action           {item.index + 1} {item.step.name}')
    return lines


def refusal_lines(err: ProgramError) -> list[str]:
    """Return a refused program's lines: where, why and the code."""
    where = f'{err.path}:{err.line}' if err.line else err.path
    return [f'refused: {where}: {err.reason} [{err.code}]']


def teach_refusal(age: float | None, qd: np.ndarray | None) -> str | None:
    """Return why a reading ``age`` [s] old with velocities ``qd`` cannot be taught, or None."""
    if age is None:
        return 'no joint states heard'
    if age > TEACH_MAX_AGE:
        return f'the joint states are stale ({age:.2f} s old, more than {TEACH_MAX_AGE:g} s)'
    if qd is not None and np.abs(qd).max() > TEACH_SPEED:
        return (f'the arm moves (a joint at {np.abs(qd).max():.4f} rad/s, more than '
                f'{TEACH_SPEED:g}): teach at rest')
    return None


def reached_error(arm: ArmModel, q: np.ndarray, target_q: np.ndarray) -> tuple[float, float]:
    """Return the largest joint error [rad] and the tool's distance [m] from ``target_q``."""
    joint = float(np.abs(np.asarray(q) - np.asarray(target_q)).max())
    tool = np.linalg.norm(fk(arm, np.asarray(q))[:3, 3] - fk(arm, np.asarray(target_q))[:3, 3])
    return joint, float(tool)
