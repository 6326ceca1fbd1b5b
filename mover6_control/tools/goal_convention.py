"""
The goal command's convention and its result line, without ROS.

Poses are the flange (link6) in base_link: X Y Z [m], then A B C [rad] as the Mover6 report
writes goals: ZYX Euler angles applied to the flange's home orientation (``pose_from_goal``), or
base-frame angles with ``absolute``; ``poses_from_numbers`` reads the command's numbers and
``format_outcome`` writes the one RESULT line of an ``Outcome``, with the pose reached in the
goal's own convention (``goal_from_pose``). The exit codes are the command's (``goal_cli``).
"""

import math
from typing import Optional, Sequence

from mover6_control.errors import NonFiniteError, ShapeError
from mover6_control.kinematics.arm import ArmModel, mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import (euler_zyx_near, goal_relative_to_start,
                                                 pose_from_xyzabc)
from mover6_control.values import ToolPose
import numpy as np

EXIT_ARRIVED, EXIT_FAILED, EXIT_REFUSED, EXIT_NO_NODES = 0, 1, 2, 3
# Within this [rad] of gimbal lock (B = +-pi/2) a reached pose is printed with B = +-pi/2 and the
# A/C split nearest the goal's angles: closer to lock the split follows the arm's tiny error.
PRINT_LOCK_TOL = 1e-3


def home_pose(arm: ArmModel) -> np.ndarray:
    """Return the flange pose (4, 4) at q = 0, by forward kinematics of ``arm``."""
    return fk(arm, np.zeros(arm.n_joints))


def pose_from_goal(arm: ArmModel, x: float, y: float, z: float, a: float, b: float, c: float,
                   absolute: bool = False) -> np.ndarray:
    """
    Return the pose (4, 4) of a goal typed as X Y Z [m] A B C [rad].

    By default as the Mover6 report: ``R = R_home Rz(A) Ry(B) Rx(C)``, ``R_home`` the flange
    orientation at q = 0; with ``absolute`` base-frame ZYX angles, ``R = Rz(A) Ry(B) Rx(C)``.
    """
    if absolute:
        return pose_from_xyzabc(x, y, z, a, b, c)
    return goal_relative_to_start(home_pose(arm), x, y, z, a, b, c)


def goal_from_pose(arm: ArmModel, T: np.ndarray, absolute: bool = False,
                   ref: Sequence[float] = (0.0, 0.0, 0.0)) -> tuple:
    """
    Return X Y Z [m] A B C [rad] of pose ``T`` (4, 4) in the goal convention (``pose_from_goal``).

    Of the equivalent angle triples the one nearest ``ref`` (the goal's angles) is returned.
    """
    T = np.asarray(T, dtype=float)
    R = T[:3, :3] if absolute else home_pose(arm)[:3, :3].T @ T[:3, :3]
    angles = euler_zyx_near(R, ref, lock_tol=PRINT_LOCK_TOL)
    return tuple(float(v) for v in T[:3, 3]) + tuple(angles)


def format_numbers(values: Sequence[float]) -> str:
    """Return numbers as text with 4 decimals and no negative zero."""
    return ' '.join('0.0000' if abs(v) < 5e-5 else f'{v:.4f}' for v in values)


class Outcome:
    """What became of one goal."""

    def __init__(self, code, text, **figures):
        self.code = code
        self.text = text
        self.figures = figures

    @property
    def arrived(self) -> bool:
        """Return True when the arm arrived."""
        return self.code == EXIT_ARRIVED

    def __repr__(self):
        """Return a one-line description."""
        return f'Outcome({self.code}, {self.text!r}, {self.figures})'


def poses_from_numbers(numbers: Sequence[float], quat: bool, arm: Optional[ArmModel] = None,
                       absolute: bool = False) -> tuple[ToolPose, ...]:
    """
    Return poses from groups of 6 numbers (X Y Z A B C) or 7 (X Y Z qx qy qz qw), checked once.

    A B C follow ``pose_from_goal`` (relative to the home orientation of ``arm``, default the
    Mover6, unless ``absolute``); a quaternion is in the base frame. Each pose is a
    ``values.ToolPose``: the goal command's edge, as ``conversions`` is the nodes'. Raises
    ``InvalidInputError`` with its code (``bad_shape``, ``non_finite``, ``bad_quaternion``).
    """
    arm = mover6() if arm is None else arm
    size = 7 if quat else 6
    if len(numbers) == 0 or len(numbers) % size:
        form = 'X Y Z QX QY QZ QW' if quat else 'X Y Z A B C'
        raise ShapeError(f'a pose is {size} numbers ({form}); got {len(numbers)} numbers')
    if not all(math.isfinite(v) for v in numbers):
        raise NonFiniteError(f'pose numbers must be finite, got {numbers}')
    out = []
    for i in range(0, len(numbers), size):
        group = numbers[i:i + size]
        if quat:
            out.append(ToolPose.from_position_quaternion(group[:3], group[3:], 'goal'))
        else:       # finite angles make a rotation: nothing left to check
            out.append(ToolPose.computed(pose_from_goal(arm, *group, absolute=absolute)))
    return tuple(out)


def parabola_peak(T_start: np.ndarray, T_goal: np.ndarray, peak_height: float) -> np.ndarray:
    """
    Return the peak pose (4, 4) of a parabolic move: ``peak_height`` [m] above the mid-point.

    The mid-point of the start and goal tool positions, raised along base z, with the start's
    orientation: the goal command sends it, then the goal, on /path_goal/parabolic.
    """
    T_peak = np.array(T_start, dtype=float)
    T_peak[:3, 3] = (0.5 * (T_peak[:3, 3] + np.asarray(T_goal)[:3, 3])
                     + np.array([0.0, 0.0, peak_height]))
    return T_peak


def format_outcome(outcome: Outcome, convention: Optional[tuple] = None) -> str:
    """
    Return the one result line of an outcome.

    ``convention`` (arm, absolute, reference angles) adds the pose reached, or for a refusal the
    closest pose the planner found, as ``X Y Z A B C`` in the goal's convention
    (``goal_from_pose``).
    """
    f = outcome.figures
    parts = []
    if 'final_joint_error' in f:
        parts.append(f'final joint error {f["final_joint_error"]:.4f} rad')
    if 'final_position_error' in f:
        parts.append(f'final tool position error {f["final_position_error"] * 1e3:.2f} mm')
    if 'final_orientation_error' in f:
        parts.append(f'orientation error {f["final_orientation_error"]:.4f} rad')
    if 'duration' in f:
        parts.append(f'{f["duration"]:.2f} s')
    word = {EXIT_ARRIVED: 'arrived', EXIT_REFUSED: 'refused'}.get(outcome.code, 'failed')
    text = '' if outcome.arrived else f' {outcome.text}'
    line = f'RESULT {word}:{text}' + (' (' + ', '.join(parts) + ')' if parts else '')
    if convention is not None:
        arm, absolute, ref = convention
        form = 'A B C base frame' if absolute else 'A B C from home'
        if 'reached_pose' in f:
            pose = goal_from_pose(arm, f['reached_pose'], absolute, ref)
            line += f'; reached X Y Z {form}: {format_numbers(pose)}'
        closest = str(f.get('closest_pose_xyzabc', '')).split()
        if len(closest) == 6:
            T = pose_from_xyzabc(*(float(v) for v in closest))
            pose = goal_from_pose(arm, T, absolute, ref)
            line += f'; closest pose inside the joint limits, X Y Z {form}: {format_numbers(pose)}'
    return line
