"""
Taught points: a name, the arm's joint positions and the tool pose they give, in a YAML file.

The file is the user's to read and edit::

    points:
      above_pick:
        joints: [0.1, 0.3, 0.4, 0.0, 0.5, 0.0]      # [rad], joints 1-6
        pose: [0.35, 0.05, 0.2, 0.0, 0.0, 0.0]       # X Y Z [m] A B C [rad], for reading

``joints`` is what a point is; ``pose`` is written from them (forward kinematics, in the goal
convention of the Mover6 report: ``pose_convention``) and recomputed on load, so an edited
``pose`` changes nothing. ``PointBook`` is the file's content, changed only into a new book
(``taught``, ``renamed``, ``deleted``).
"""

from __future__ import annotations

from dataclasses import dataclass
import os
import re

from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk
from mover6_control.programs.marked_yaml import Marked, read_marked
from mover6_control.programs.pose_convention import pose_numbers
from mover6_control.programs.program_error import ProgramError
import numpy as np

NAME_PATTERN = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')
POINT_KEYS = ('joints', 'pose')


@dataclass(frozen=True)
class Point:
    """A taught point: its name, joint positions (6,) [rad] and tool pose X Y Z A B C."""

    name: str
    joints: tuple
    pose: tuple

    @classmethod
    def of(cls, arm: ArmModel, name: str, joints, path: str = '', line: int = 0) -> Point:
        """Return the point at ``joints``, checked: a name, finite values within the limits."""
        check_name(name, path, line)
        q = np.asarray(joints, dtype=float).reshape(-1) if _numbers(joints) else None
        if q is None or q.size != arm.n_joints or not np.all(np.isfinite(q)):
            raise ProgramError(path, line, f'point "{name}": joints must be {arm.n_joints} '
                               f'finite numbers [rad], got {joints!r}', 'bad_value')
        if not arm.within_limits(q):
            raise ProgramError(path, line, f'point "{name}" is outside the joint limits: '
                               + '; '.join(arm.limit_violations(q)), 'bad_value')
        pose = pose_numbers(arm, fk(arm, q))
        return cls(name, tuple(float(v) for v in q), tuple(round(v, 6) for v in pose))

    @property
    def q(self) -> np.ndarray:
        """Return the joint positions (6,) [rad]."""
        return np.array(self.joints)


def _numbers(values) -> bool:
    if not isinstance(values, (list, tuple, np.ndarray)):
        return False
    return all(isinstance(v, (int, float, np.floating)) and not isinstance(v, bool)
               for v in values)


def check_name(name, path: str = '', line: int = 0) -> str:
    """Return ``name`` when it is a point name (letters, digits, underscores), else raise."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise ProgramError(path, line, f'a point name is letters, digits and underscores, not '
                           f'starting with a digit; got {name!r}', 'bad_value')
    return name


@dataclass(frozen=True)
class PointBook:
    """The points of one file, by name, in the file's order; ``path`` is the file."""

    path: str
    points: tuple = ()
    lines: tuple = ()          # the line of each point in the file (0: not from a file)

    def names(self) -> list[str]:
        """Return the point names in order."""
        return [p.name for p in self.points]

    def get(self, name: str) -> Point | None:
        """Return the point called ``name``, or None."""
        return next((p for p in self.points if p.name == name), None)

    def line_of(self, name: str) -> int:
        """Return the line of point ``name`` in its file (0 when not known)."""
        for point, line in zip(self.points, self.lines):
            if point.name == name:
                return line
        return 0

    def taught(self, point: Point, replace: bool = False) -> PointBook:
        """Return the book with ``point`` added (or replacing its namesake with ``replace``)."""
        if self.get(point.name) is not None and not replace:
            raise ProgramError(self.path, self.line_of(point.name),
                               f'point "{point.name}" exists already (replace it, or rename '
                               'or delete it first)', 'duplicate')
        kept = [(p, n) for p, n in zip(self.points, self.lines) if p.name != point.name]
        return PointBook(self.path, tuple(p for p, _ in kept) + (point,),
                         tuple(n for _, n in kept) + (0,))

    def renamed(self, old: str, new: str) -> PointBook:
        """Return the book with point ``old`` called ``new``."""
        self._need(old)
        check_name(new, self.path)
        if self.get(new) is not None:
            raise ProgramError(self.path, self.line_of(new), f'point "{new}" exists already',
                               'duplicate')
        points = tuple(Point(new, p.joints, p.pose) if p.name == old else p
                       for p in self.points)
        return PointBook(self.path, points, self.lines)

    def deleted(self, name: str) -> PointBook:
        """Return the book without point ``name``."""
        self._need(name)
        kept = [(p, n) for p, n in zip(self.points, self.lines) if p.name != name]
        return PointBook(self.path, tuple(p for p, _ in kept), tuple(n for _, n in kept))

    def _need(self, name):
        if self.get(name) is None:
            raise ProgramError(self.path, 0, f'no point "{name}" (points: '
                               f'{", ".join(self.names()) or "none"})', 'unknown_point')

    def text(self) -> str:
        """Return the file's YAML text."""
        lines = ['# Taught points: joints [rad] (joints 1-6) are the point; pose (X Y Z [m],',
                 '# A B C [rad] from the home orientation) is written from them for reading.',
                 'points:' + ('' if self.points else ' {}')]
        for p in self.points:
            lines.append(f'  {p.name}:')
            lines.append('    joints: [' + ', '.join(f'{v:.6f}' for v in p.joints) + ']')
            lines.append('    pose: [' + ', '.join(f'{v:.6f}' for v in p.pose) + ']')
        return '\n'.join(lines) + '\n'

    def save(self) -> None:
        """Write the book to its file (through a temporary file: a crash leaves the old one)."""
        folder = os.path.dirname(os.path.abspath(self.path))
        os.makedirs(folder, exist_ok=True)
        tmp = self.path + '.tmp'
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(self.text())
        os.replace(tmp, self.path)


def book_from_marked(arm: ArmModel, doc: Marked, path: str) -> PointBook:
    """Return the ``PointBook`` of a marked document (``{points: {name: {joints, pose}}}``)."""
    if not isinstance(doc.value, dict):
        raise ProgramError(path, doc.line, 'a points file is a mapping with key "points"',
                           'syntax')
    for key, value in doc.value.items():
        if key != 'points':
            raise ProgramError(path, value.line, f'unknown key "{key}" (expected "points")',
                               'unknown_key')
    entries = doc.value.get('points')
    if entries is None or entries.value is None:
        return PointBook(path)
    if not isinstance(entries.value, dict):
        raise ProgramError(path, entries.line, '"points" is a mapping of name to point',
                           'syntax')
    points, lines = [], []
    for name, entry in entries.value.items():
        if not isinstance(entry.value, dict):
            raise ProgramError(path, entry.line, f'point "{name}" is a mapping with "joints"',
                               'syntax')
        for key, value in entry.value.items():
            if key not in POINT_KEYS:
                raise ProgramError(path, value.line, f'point "{name}": unknown key "{key}" '
                                   f'(expected one of {", ".join(POINT_KEYS)})', 'unknown_key')
        if 'joints' not in entry.value:
            raise ProgramError(path, entry.line, f'point "{name}" has no "joints"', 'missing')
        joints = entry.value['joints']
        points.append(Point.of(arm, name, joints.plain(), path, joints.line))
        lines.append(entry.line)
    return PointBook(path, tuple(points), tuple(lines))


def load_points(arm: ArmModel, path: str) -> PointBook:
    """Return the book of the file at ``path``; a missing file is an empty book."""
    if not os.path.exists(path):
        return PointBook(path)
    return book_from_marked(arm, read_marked(path), path)
