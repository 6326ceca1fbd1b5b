"""
The one error of a point or program file, or of a program's plan: file, line, reason and code.

``PROGRAM_CODES`` is the table of its codes, each with its meaning; a program refused by the
plan carries the planner's reason (a key of ``errors.REASONS``) as its code.
"""

from __future__ import annotations

from mover6_control.errors import Mover6Error, REASONS

PROGRAM_CODES = {
    'syntax': 'the file is no YAML, or its top level is not a mapping',
    'missing': 'a required key is missing',
    'unknown_key': 'a key the schema does not have (a typo)',
    'bad_value': 'a value of the wrong type or outside its range',
    'unknown_point': 'a step names a point the points file does not hold',
    'speed_limit': "a speed above the limits (a lin's tool speed above Pilz's Cartesian "
                   'limits, a speed fraction above 1)',
    'blend_radius': 'a blend radius larger than half of a neighbouring segment, or a blend '
                    'with no move after it',
    'no_gripper': 'a gripper step on a stack without a gripper',
    'duplicate': 'a point name taken twice',
    'teach_refused': 'a point taught while the arm moves or from stale joint states',
}


class ProgramError(Mover6Error, ValueError):
    """
    A program or point file refused, or a program whose plan fails: where and why.

    ``path`` and ``line`` (1-based; 0 when the error has no line) locate it, ``reason`` says
    why, ``code`` is a key of ``PROGRAM_CODES`` or of ``errors.REASONS``; ``step`` is the
    index of the step in the run order (-1 for none).
    """

    def __init__(self, path: str, line: int, reason: str, code: str, step: int = -1) -> None:
        """Keep where and why; raise ``KeyError`` for a code no table holds."""
        if code not in PROGRAM_CODES and code not in REASONS:
            raise KeyError(f'no program code {code!r}')
        where = f'{path}:{line}' if line else path
        super().__init__(f'{where}: {reason}')
        self.path = path
        self.line = int(line)
        self.reason = reason
        self.code = code
        self.step = int(step)
