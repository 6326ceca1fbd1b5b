"""
A program file: YAML steps, checked at load into ``steps`` values with the file and line.

The schema (``docs/programs.md`` has it in full)::

    program: pick_and_place        # a name (optional)
    points: points.yaml            # the points file, relative to this file (optional)
    steps:
      - ptp: above_pick            # to a taught point, or {pose: [X, Y, Z, A, B, C]}
        blend: 0.02                # [m] round the corner into the next move (optional)
      - lin: pick
        speed: 0.05                # [m/s] tool speed (default Pilz's max_trans_vel)
        rot_speed: 0.3             # [rad/s] tool turn rate (default Pilz's max_rot_vel)
      - circ: end
        via: middle
      - speed: 0.5                 # joint speed fraction of the moves after it
      - gripper: close             # or open
      - wait: 0.5                  # [s], or {input: 1, state: high, timeout: 10}
      - repeat: 3
        steps: [...]

Refused at load (``ProgramError`` with the line): a key the schema does not have, a point the
points file does not hold, a speed above the limits, a blend with no move after it or larger
than half of a neighbouring segment, a gripper step when the stack has no gripper.
"""

from __future__ import annotations

from dataclasses import dataclass
import os

from mover6_control.hardware.protocol import INPUT_CHANNELS
from mover6_control.kinematics.arm import ArmModel
from mover6_control.kinematics.forward import fk
from mover6_control.programs.limits import CartesianLimits
from mover6_control.programs.marked_yaml import Marked, read_marked
from mover6_control.programs.points import load_points, PointBook
from mover6_control.programs.pose_convention import pose_matrix
from mover6_control.programs.program_error import ProgramError
from mover6_control.programs.steps import (GRIPPER_ACTIONS, GripperStep, INPUT_STATES, Move,
                                           MOVE_KINDS, RepeatStep, RunStep, SpeedStep, Target,
                                           unrolled, WaitStep)
import numpy as np

TOP_KEYS = ('program', 'points', 'steps')
STEP_KEYS = {'ptp': ('ptp', 'blend'),
             'lin': ('lin', 'speed', 'rot_speed', 'blend'),
             'circ': ('circ', 'via', 'speed', 'rot_speed', 'blend'),
             'speed': ('speed',),
             'gripper': ('gripper',),
             'wait': ('wait',),
             'repeat': ('repeat', 'steps')}
# The kind keys, in the order a step is recognised by ('speed' last: it is also a lin's key).
STEP_KINDS = ('ptp', 'lin', 'circ', 'gripper', 'wait', 'repeat', 'speed')
WAIT_KEYS = ('input', 'state', 'timeout')
MAX_REPEAT = 1000
MAX_WAIT = 3600.0       # [s]


@dataclass(frozen=True)
class Program:
    """A checked program: its file, name, points, steps and the run order (repeats unrolled)."""

    path: str
    name: str
    points: PointBook
    steps: tuple
    run: tuple              # RunStep per step in the run order

    def moves(self) -> list[RunStep]:
        """Return the run steps that move the arm."""
        return [r for r in self.run if isinstance(r.step, Move)]


@dataclass(frozen=True)
class LoadContext:
    """What a program is checked against: the arm, the points, the limits, the gripper."""

    arm: ArmModel
    points: PointBook
    limits: CartesianLimits
    has_gripper: bool
    path: str


def _fail(ctx, line, reason, code='bad_value'):
    raise ProgramError(ctx.path, line, reason, code)


def _number(ctx, marked, what, low, high, low_open=False):
    value = marked.value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        _fail(ctx, marked.line, f'{what} must be a number, got {value!r}')
    if value < low or (low_open and value <= low):
        _fail(ctx, marked.line, f'{what} must be {">" if low_open else ">="} {low:g}, '
              f'got {value:g}')
    if value > high:
        _fail(ctx, marked.line, f'{what} must be <= {high:g}, got {value:g}')
    return float(value)


def _target(ctx, marked, what):
    value = marked.value
    if isinstance(value, str):
        point = ctx.points.get(value)
        if point is None:
            names = ', '.join(ctx.points.names()) or 'none'
            _fail(ctx, marked.line, f'{what}: unknown point "{value}" (the points of '
                  f'{ctx.points.path}: {names})', 'unknown_point')
        return Target(point.name, fk(ctx.arm, point.q), point.joints)
    if isinstance(value, dict) and set(value) == {'pose'}:
        numbers = value['pose'].plain()
        if (not isinstance(numbers, list) or len(numbers) != 6
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                           and np.isfinite(v) for v in numbers)):
            _fail(ctx, value['pose'].line, f'{what}: a pose is 6 numbers X Y Z [m] A B C '
                  f'[rad], got {numbers!r}')
        label = 'pose [' + ' '.join(f'{v:g}' for v in numbers) + ']'
        return Target(label, pose_matrix(ctx.arm, *[float(v) for v in numbers]))
    _fail(ctx, marked.line, f'{what}: a point name or {{pose: [X, Y, Z, A, B, C]}}, got '
          f'{marked.plain()!r}')


def _move(ctx, kind, entries, line):
    target = _target(ctx, entries[kind], kind)
    if kind == 'circ' and 'via' not in entries:
        _fail(ctx, line, 'circ needs a via point ("via")', 'missing')
    via = _target(ctx, entries['via'], 'via') if kind == 'circ' else None
    limits = ctx.limits
    speed = rot_speed = 0.0
    if kind in ('lin', 'circ'):
        speed, rot_speed = limits.max_trans_vel, limits.max_rot_vel
        for key, high, unit, limit in (('speed', limits.max_trans_vel, 'm/s', 'max_trans_vel'),
                                       ('rot_speed', limits.max_rot_vel, 'rad/s',
                                        'max_rot_vel')):
            if key not in entries:
                continue
            value = _number(ctx, entries[key], f'{kind} {key}', 0.0, np.inf, low_open=True)
            if value > high:
                _fail(ctx, entries[key].line, f'{kind} {key} {value:g} {unit} is above the '
                      f"Cartesian limit {high:g} {unit} (Pilz's {limit})", 'speed_limit')
            if key == 'speed':
                speed = value
            else:
                rot_speed = value
    blend = _number(ctx, entries['blend'], 'blend', 0.0, np.inf) if 'blend' in entries else 0.0
    return Move(kind, target, line, via, speed, rot_speed, blend)


def _step(ctx, marked):
    if not isinstance(marked.value, dict) or not marked.value:
        _fail(ctx, marked.line, f'a step is a mapping such as "- lin: pick", got '
              f'{marked.plain()!r}', 'syntax')
    entries = marked.value
    kind = next((k for k in STEP_KINDS if k in entries), None)
    if kind is None:
        key = next(iter(entries))
        _fail(ctx, entries[key].line, f'unknown step "{key}" (steps: {", ".join(STEP_KINDS)})',
              'unknown_key')
    for key, value in entries.items():
        if key not in STEP_KEYS[kind]:
            _fail(ctx, value.line, f'unknown key "{key}" in a {kind} step (its keys: '
                  f'{", ".join(STEP_KEYS[kind])})', 'unknown_key')
    line = marked.line
    if kind in MOVE_KINDS:
        return _move(ctx, kind, entries, line)
    value = entries[kind]
    if kind == 'speed':
        fraction = _number(ctx, value, 'speed fraction', 0.0, np.inf, low_open=True)
        if fraction > 1.0:
            _fail(ctx, value.line, f'speed fraction {fraction:g} is above 1 (the joint limits)',
                  'speed_limit')
        return SpeedStep(fraction, line)
    if kind == 'gripper':
        if value.value not in GRIPPER_ACTIONS:
            _fail(ctx, value.line, f'gripper is open or close, got {value.plain()!r}')
        if not ctx.has_gripper:
            _fail(ctx, value.line, f'gripper {value.value}: this stack has no gripper (no '
                  'GripperCommand server)', 'no_gripper')
        return GripperStep(value.value, line)
    if kind == 'wait':
        return _wait(ctx, value, line)
    count = value.value
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_REPEAT:
        _fail(ctx, value.line, f'repeat takes a count 1-{MAX_REPEAT}, got {value.plain()!r}')
    if 'steps' not in entries:
        _fail(ctx, line, 'repeat needs its "steps"', 'missing')
    return RepeatStep(count, _steps(ctx, entries['steps']), line)


def _wait(ctx, value, line):
    if not isinstance(value.value, dict):
        return WaitStep(line, seconds=_number(ctx, value, 'wait', 0.0, MAX_WAIT))
    for key, item in value.value.items():
        if key not in WAIT_KEYS:
            _fail(ctx, item.line, f'unknown key "{key}" in a wait (its keys: '
                  f'{", ".join(WAIT_KEYS)})', 'unknown_key')
    if 'input' not in value.value:
        _fail(ctx, value.line, 'a wait for an input needs "input" (a channel 1-'
              f'{len(INPUT_CHANNELS)})', 'missing')
    channel = value.value['input']
    if (isinstance(channel.value, bool) or not isinstance(channel.value, int)
            or not 1 <= channel.value <= len(INPUT_CHANNELS)):
        _fail(ctx, channel.line, f'input is a channel 1-{len(INPUT_CHANNELS)}, got '
              f'{channel.plain()!r}')
    state = value.value.get('state', Marked('high', value.line))
    if state.value not in INPUT_STATES:
        _fail(ctx, state.line, f'state is high or low, got {state.plain()!r}')
    timeout = (_number(ctx, value.value['timeout'], 'timeout', 0.0, MAX_WAIT, low_open=True)
               if 'timeout' in value.value else MAX_WAIT)
    return WaitStep(line, channel=channel.value, state=state.value, timeout=timeout)


def _steps(ctx, marked):
    if not isinstance(marked.value, list) or not marked.value:
        _fail(ctx, marked.line, '"steps" is a list of at least one step', 'syntax')
    return tuple(_step(ctx, item) for item in marked.value)


def check_blends(path: str, run: list, start: np.ndarray | None = None) -> None:
    """
    Raise ``ProgramError`` (code 'blend_radius') for a blend the run order cannot make.

    A blend needs a move right after it; its radius is at most half of the segment into its
    corner and half of the one out of it (straight tool distances between the targets; the
    first move's segment starts at ``start``, the tool position, when given).
    """
    previous = start
    for i, item in enumerate(run):
        step = item.step
        if not isinstance(step, Move):
            continue
        corner = step.target.position
        if step.blend > 0.0:
            after = run[i + 1].step if i + 1 < len(run) else None
            where = f'{step.name} (step {i + 1})'
            if not isinstance(after, Move):
                what = 'the program ends' if after is None else f'"{after.name}" follows'
                raise ProgramError(path, step.line, f'blend {step.blend:g} m on {where}: '
                                   f'{what}, and a blend needs a move after it',
                                   'blend_radius', i)
            into = (np.linalg.norm(corner - previous) if previous is not None else np.inf)
            out_of = np.linalg.norm(after.target.position - corner)
            half = 0.5 * min(into, out_of)
            if step.blend > half:
                side = 'into' if into <= out_of else 'out of'
                raise ProgramError(path, step.line, f'blend {step.blend:g} m on {where} is '
                                   f'larger than half of the segment {side} its corner '
                                   f'({half:.4f} m)', 'blend_radius', i)
        previous = corner


def load_program(arm: ArmModel, path: str, limits: CartesianLimits | None = None,
                 has_gripper: bool = True, points_path: str | None = None) -> Program:
    """
    Return the checked ``Program`` of the file at ``path``.

    ``points_path`` overrides the file's ``points`` key (default ``points.yaml`` beside the
    program). Raises ``ProgramError`` with the file, line and reason.
    """
    doc = read_marked(path)
    return program_from_marked(arm, doc, path, limits, has_gripper, points_path)


def program_from_marked(arm: ArmModel, doc: Marked, path: str,
                        limits: CartesianLimits | None = None, has_gripper: bool = True,
                        points_path: str | None = None) -> Program:
    """Return the checked ``Program`` of a marked document (``load_program``)."""
    limits = CartesianLimits.load() if limits is None else limits
    if not isinstance(doc.value, dict):
        raise ProgramError(path, doc.line, 'a program file is a mapping with "steps"', 'syntax')
    for key, value in doc.value.items():
        if key not in TOP_KEYS:
            raise ProgramError(path, value.line, f'unknown key "{key}" (the keys of a program: '
                               f'{", ".join(TOP_KEYS)})', 'unknown_key')
    if 'steps' not in doc.value:
        raise ProgramError(path, doc.line, 'a program needs "steps"', 'missing')
    folder = os.path.dirname(os.path.abspath(path))
    if points_path is None:
        entry = doc.value.get('points', Marked('points.yaml', doc.line))
        if not isinstance(entry.value, str):
            raise ProgramError(path, entry.line, f'"points" is a file name, got '
                               f'{entry.plain()!r}', 'bad_value')
        points_path = os.path.join(folder, entry.value)
    points = load_points(arm, points_path)
    name = doc.value.get('program', Marked(os.path.splitext(os.path.basename(path))[0], 0))
    ctx = LoadContext(arm, points, limits, has_gripper, path)
    steps = _steps(ctx, doc.value['steps'])
    run = unrolled(steps)
    check_blends(path, run)
    return Program(path, str(name.value), points, steps, tuple(run))
