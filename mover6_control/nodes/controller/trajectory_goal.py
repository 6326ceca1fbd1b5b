"""
A ``FollowJointTrajectory`` goal read and checked, and the result codes of its motion.

``map_goal`` and ``map_timing`` turn a goal's ``JointTrajectory`` into the controller's
waypoints and ``Timing``, its joints mapped by name (a goal that cannot be used raises
``ValueError(error_code, reason)``); ``tolerances`` and ``violations`` read and check its path
and goal tolerances; ``ended_code`` is the error code of a motion that ended other than arrived,
decided by the controller's ``cause``. The server that runs a goal:
``nodes/controller/trajectory_server.py``.
"""

from typing import Optional, Sequence

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from mover6_control.control.status import Cause, StatusKey
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError
from trajectory_msgs.msg import JointTrajectory

Result = FollowJointTrajectory.Result


def map_goal(trajectory: JointTrajectory, joint_names: Sequence[str]) -> list:
    """
    Return the waypoints (N, n) [rad] of a JointTrajectory in ``joint_names`` order.

    Raises ``ValueError`` with ``(error_code, reason)`` as its arguments when the joints or the
    points are not usable.
    """
    names = list(trajectory.joint_names)
    if sorted(names) != sorted(joint_names) or len(set(names)) != len(names):
        raise ValueError(Result.INVALID_JOINTS,
                         f'the goal names joints {names}; this controller drives exactly '
                         f'{list(joint_names)} (any order, each once)')
    if not trajectory.points:
        raise ValueError(Result.INVALID_GOAL, 'the trajectory has no points')
    order = [names.index(name) for name in joint_names]
    rows, last = [], -1.0
    for k, point in enumerate(trajectory.points):
        if len(point.positions) != len(names):
            raise ValueError(Result.INVALID_GOAL, f'point {k} has {len(point.positions)} '
                                                  f'positions for {len(names)} joints')
        if point.velocities and len(point.velocities) != len(names):
            raise ValueError(Result.INVALID_GOAL, f'point {k} has {len(point.velocities)} '
                                                  f'velocities for {len(names)} joints')
        t = point.time_from_start.sec + point.time_from_start.nanosec * 1e-9
        if t < last:
            raise ValueError(Result.INVALID_GOAL,
                             f'point {k}: time_from_start {t:.3f} s is before the point before')
        last = t
        rows.append([float(point.positions[i]) for i in order])
    return rows


def map_timing(trajectory: JointTrajectory, joint_names: Sequence[str]) -> Timing:
    """
    Return the ``Timing`` of a JointTrajectory's points in ``joint_names`` order.

    Raises ``ValueError`` with ``(error_code, reason)`` when velocities or accelerations are
    given for some points and not others, have the wrong length or are not finite.
    """
    names = list(trajectory.joint_names)
    order = [names.index(name) for name in joint_names]
    points = list(trajectory.points)
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in points]
    columns = {}
    for field in ('velocities', 'accelerations'):
        given = [len(getattr(p, field)) > 0 for p in points]
        if any(given) and not all(given):
            raise ValueError(Result.INVALID_GOAL, f'{field} are given for some points and not '
                                                  f'others: give them for all or none')
        if not any(given):
            continue
        for k, point in enumerate(points):
            if len(getattr(point, field)) != len(names):
                raise ValueError(Result.INVALID_GOAL,
                                 f'point {k} has {len(getattr(point, field))} {field} for '
                                 f'{len(names)} joints')
        columns[field] = [[float(getattr(p, field)[i]) for i in order] for p in points]
    try:
        return Timing(times, columns.get('velocities'), columns.get('accelerations'))
    except InvalidInputError as err:
        raise ValueError(Result.INVALID_GOAL, str(err))


def ended_code(values: dict) -> int:
    """
    Return the error code of a goal whose motion ended other than arrived, from its status.

    Decided by the controller's ``cause`` (``status.Cause``), never by the words of its reason:
    not settled within the goal tolerance is GOAL_TOLERANCE_VIOLATED; the path tolerance left,
    stale states or a stop is PATH_TOLERANCE_VIOLATED.
    """
    if values.get(StatusKey.CAUSE) == Cause.GOAL_TOLERANCE:
        return Result.GOAL_TOLERANCE_VIOLATED
    return Result.PATH_TOLERANCE_VIOLATED


def tolerances(entries: Sequence[JointTolerance], joint_names: Sequence[str],
               default: float) -> list:
    """Return the position tolerance per joint [rad] (None: unchecked) from JointTolerance[]."""
    tol = {name: default for name in joint_names}
    for entry in entries:
        if entry.name in tol and entry.position > 0.0:
            tol[entry.name] = entry.position
        elif entry.name in tol and entry.position < 0.0:
            tol[entry.name] = None
    return [tol[name] for name in joint_names]


def violations(error: Sequence[float], tol: Sequence[Optional[float]],
               joint_names: Sequence[str]) -> str:
    """Return the words for each joint whose |error| exceeds its tolerance ('' when none)."""
    return '; '.join(f'{name} off by {abs(e):.4f} rad (tolerance {t:g})'
                     for name, e, t in zip(joint_names, error, tol)
                     if t is not None and abs(e) > t)
