"""
The frozen values input becomes where it enters: a tool pose, a joint jog, a joint demand.

Each is checked once, when it is made (where a message enters: ``nodes/messages/``, the goal
CLI's parser), and raises an ``InvalidInputError`` whose ``code`` (``errors.INPUT_CODES``) says
what was wrong. The layers below take the value and do not check it again: ``ToolPose.of``
passes a ``ToolPose`` through as it is and checks only a raw matrix (a caller that hands the
library raw input). A base module, like ``validation``: it imports nothing of this package but
``errors`` and ``validation``.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

from mover6_control.errors import (InvalidInputError, NonFiniteError, NotATransformError,
                                   QuaternionError, ShapeError)
from mover6_control.validation import as_finite_array
import numpy as np

ORTHONORMAL_TOL = 1e-6
"""Largest |R^T R - I| entry (and last-row error) of a matrix taken as a rigid transform."""

QUATERNION_NORM_TOL = 1e-3
"""Largest |norm - 1| of an orientation quaternion: a sender that means a rotation normalises."""


def _dot3(a, b):
    """Return the dot product of two 3-lists."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def check_rotation_rows(rows: Sequence[Sequence[float]], name: str) -> None:
    """
    Raise ``NotATransformError`` unless the 3x3 ``rows`` are orthonormal with determinant +1.

    On floats: nine numbers cost less than the set-up of array operations.
    """
    a, b, c = rows
    col = [[a[j], b[j], c[j]] for j in range(3)]
    err = max(abs(_dot3(col[0], col[0]) - 1.0), abs(_dot3(col[1], col[1]) - 1.0),
              abs(_dot3(col[2], col[2]) - 1.0), abs(_dot3(col[0], col[1])),
              abs(_dot3(col[0], col[2])), abs(_dot3(col[1], col[2])))
    if err > ORTHONORMAL_TOL:
        raise NotATransformError(f'{name} is not orthonormal (|R^T R - I| = {err:.2e})')
    det = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
           + a[2] * (b[0] * c[1] - b[1] * c[0]))
    if det < 0.0:
        raise NotATransformError(f'{name} is a reflection (det < 0), not a rotation')


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _checked_transform(T, name):
    """Return ``T`` as a new (4, 4) array after the checks of ``ToolPose.from_matrix``."""
    T = np.array(as_finite_array(T, (4, 4), name))
    rows = T.tolist()
    check_rotation_rows([row[:3] for row in rows[:3]], name + ' rotation')
    last = rows[3]
    if max(abs(last[0]), abs(last[1]), abs(last[2]), abs(last[3] - 1.0)) > ORTHONORMAL_TOL:
        raise NotATransformError(f'{name} last row must be [0, 0, 0, 1], got {last}')
    return _frozen(T)


@dataclass(frozen=True, eq=False)
class ToolPose:
    """
    A rigid transform ``matrix`` (4, 4) [m], read-only: a goal or a via pose ``T_base_tool``.

    Made by ``ToolPose(T)``, ``from_matrix`` or ``from_position_quaternion`` (all check), or by
    ``computed`` for a transform this package computed itself (forward kinematics): not checked.
    It reads as its matrix (``np.asarray(pose)``, ``pose[:3, 3]``), so numeric code takes it
    as it is and passes it on still known to be checked.
    """

    matrix: np.ndarray

    def __post_init__(self):
        """Check the matrix (``from_matrix``) and keep a read-only copy."""
        object.__setattr__(self, 'matrix', _checked_transform(self.matrix, 'pose'))

    @classmethod
    def from_matrix(cls, T: object, name: str = 'pose') -> ToolPose:
        """Return the pose of ``T`` (4, 4): finite, a proper rotation, last row [0, 0, 0, 1]."""
        return cls._unchecked(_checked_transform(T, name))

    @classmethod
    def _unchecked(cls, T):
        pose = object.__new__(cls)
        object.__setattr__(pose, 'matrix', _frozen(T))
        return pose

    @classmethod
    def from_position_quaternion(cls, position: Sequence[float], quaternion: Sequence[float],
                                 name: str = 'pose') -> ToolPose:
        """
        Return the pose at ``position`` (3,) [m] turned by ``quaternion`` (x, y, z, w).

        A quaternion whose norm is off 1 by more than ``QUATERNION_NORM_TOL`` is refused
        (``bad_quaternion``): silently normalising would hide a sender's bug.
        """
        p = as_finite_array(position, (3,), f'{name} position')
        x, y, z, w = as_finite_array(quaternion, (4,), f'{name} quaternion').tolist()
        norm = math.sqrt(x * x + y * y + z * z + w * w)
        if norm < 1e-9:
            raise QuaternionError(f'{name} quaternion is zero: it describes no rotation')
        if abs(norm - 1.0) > QUATERNION_NORM_TOL:
            raise QuaternionError(f'{name} quaternion is not unit length (norm {norm:.6f})')
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
        T = np.eye(4)
        T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        T[:3, 3] = p
        return cls._unchecked(T)

    @classmethod
    def computed(cls, T: np.ndarray) -> ToolPose:
        """Return a transform this package made itself (by forward kinematics), unchecked."""
        return cls._unchecked(np.array(T, dtype=float))

    @classmethod
    def of(cls, T: object, name: str = 'pose') -> ToolPose:
        """Return ``T`` itself when it is a ``ToolPose``; else check it (``from_matrix``)."""
        return T if isinstance(T, ToolPose) else cls.from_matrix(T, name)

    def __array__(self, dtype=None, copy=None):
        """Return the read-only matrix (a copy for another ``dtype`` or ``copy=True``)."""
        if dtype is None and not copy:
            return self.matrix
        return np.array(self.matrix, dtype=dtype)

    def __getitem__(self, index):
        """Return ``matrix[index]`` (read-only)."""
        return self.matrix[index]

    @property
    def position(self) -> np.ndarray:
        """Return the tool's place: (3,) [m]."""
        return self.matrix[:3, 3]

    @property
    def rotation(self) -> np.ndarray:
        """Return the rotation matrix (3, 3)."""
        return self.matrix[:3, :3]


def poses_of(poses: object, name: str = 'via pose') -> list[ToolPose]:
    """
    Return poses given as ``ToolPose`` values or raw matrices (k, 4, 4) as a list of poses.

    A ``ToolPose`` passes as it is; each raw matrix is checked (``ToolPose.from_matrix``).
    """
    if isinstance(poses, ToolPose):
        return [poses]
    if not isinstance(poses, (list, tuple)):
        try:
            poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
        except (TypeError, ValueError) as err:
            raise ShapeError(f'{name}s must be 4x4 matrices: {err}'[:300]) from err
    return [ToolPose.of(T, f'{name} {i}') for i, T in enumerate(poses)]


@dataclass(frozen=True)
class JogRequest:
    """
    A joint jog: joint ``names`` and their ``velocities`` (a JointJog's velocities, unscaled).

    Checked when made (``from_fields``): at least one joint, as many velocities as names, no
    name twice, every velocity finite. Whether the names are the arm's, and the speeds within
    its limits, its consumer knows (``indices``, the driver's and the simulator's limits).
    """

    names: tuple[str, ...]
    velocities: tuple[float, ...]

    def __post_init__(self):
        """Check the names and the velocities; keep them as tuples."""
        names = tuple(str(n) for n in self.names)
        if not names:
            raise InvalidInputError('JointJog names no joints', 'empty')
        try:
            values = tuple(float(v) for v in self.velocities)
        except (TypeError, ValueError) as err:
            raise ShapeError(f'JointJog velocities are not numbers: {err}'[:300]) from err
        if len(values) != len(names):
            raise InvalidInputError(
                f'JointJog has {len(names)} joint names but {len(values)} velocities', 'length')
        if len(set(names)) != len(names):
            raise InvalidInputError(f'JointJog names a joint twice: {list(names)}'[:300],
                                    'names')
        if not all(math.isfinite(v) for v in values):
            raise NonFiniteError(f'JointJog has non-finite velocities: {list(values)}'[:300])
        object.__setattr__(self, 'names', names)
        object.__setattr__(self, 'velocities', values)

    @classmethod
    def from_fields(cls, names: Sequence[str], velocities: Sequence[float],
                    displacements: Sequence[float] = ()) -> JogRequest:
        """Return the jog of a JointJog's fields, or raise with the code of what is wrong."""
        if len(displacements):
            raise InvalidInputError('JointJog displacements are not supported: send velocities',
                                    'displacements')
        return cls(names, velocities)

    def indices(self, joint_names: Sequence[str]) -> tuple[int, ...]:
        """Return the index of each named joint in ``joint_names``; raise for a name not there."""
        index = {name: i for i, name in enumerate(joint_names)}
        unknown = [n for n in self.names if n not in index]
        if unknown:
            raise InvalidInputError(f'JointJog names unknown joints {unknown[:6]}; the arm has '
                                    f'{list(joint_names)}'[:300], 'unknown_joint')
        return tuple(index[n] for n in self.names)


@dataclass(frozen=True, eq=False)
class JointDemand:
    """
    Joint waypoints ``positions`` (n, joints) [rad], read-only: what /joint_demands carries.

    Checked when made (``from_rows``): at least one waypoint, the joint count, finite values.
    """

    positions: np.ndarray

    def __post_init__(self):
        """Check the rows (``from_rows``) and keep a read-only copy."""
        rows = self.positions
        shape = np.shape(rows) if isinstance(rows, np.ndarray) else ()
        n_joints = shape[1] if len(shape) == 2 and shape[1] else 6
        object.__setattr__(self, 'positions', _checked_rows(rows, n_joints))

    @classmethod
    def from_rows(cls, values: object, n_joints: int = 6) -> JointDemand:
        """Return the demand of ``values`` (n * n_joints numbers, flat or in rows), or raise."""
        demand = object.__new__(cls)
        object.__setattr__(demand, 'positions', _checked_rows(values, n_joints))
        return demand

    @property
    def n_waypoints(self) -> int:
        """Return the number of waypoints (rows)."""
        return self.positions.shape[0]


def _checked_rows(values, n_joints):
    """Return ``values`` as read-only rows (n, n_joints) after the checks of ``JointDemand``."""
    try:
        data = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as err:
        raise ShapeError(f'joint demands are not numbers: {err}'[:300]) from err
    if data.size == 0:
        raise InvalidInputError('joint demands are empty', 'empty')
    if data.size % n_joints != 0:
        raise ShapeError(f'joint demands length {data.size} is not a multiple of {n_joints}')
    if not np.all(np.isfinite(data)):
        raise NonFiniteError('joint demands have non-finite values')
    return _frozen(data.reshape(-1, n_joints))
