"""
The steps of a program, as small frozen values: moves, speed, gripper, wait and repeat.

Each step keeps the line of the program file it was written on, so an error of its plan or its
run names that line. ``program_file`` makes them from a file, checked.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

MOVE_KINDS = ('ptp', 'lin', 'circ')
GRIPPER_ACTIONS = ('open', 'close')
INPUT_STATES = ('high', 'low')


@dataclass(frozen=True)
class Target:
    """Where a move goes: a taught point (its joints) or a pose, with the pose's matrix."""

    label: str                      # the point's name, or "pose [x y z a b c]"
    T: np.ndarray                   # (4, 4) the flange pose in base_link
    joints: Optional[tuple] = None  # a point's joint positions (6,) [rad]; None for a pose

    @property
    def position(self) -> np.ndarray:
        """Return where the tool is: (3,) [m] in base_link."""
        return self.T[:3, 3]


@dataclass(frozen=True)
class Move:
    """
    A ptp (joint move), lin (straight line) or circ (arc through ``via``) to ``target``.

    ``speed`` [m/s] and ``rot_speed`` [rad/s] bound the tool on a lin or circ; ``blend`` [m] is
    the radius around ``target`` in which the motion rounds the corner into the next move
    without stopping (0: it stops at the target).
    """

    kind: str
    target: Target
    line: int
    via: Optional[Target] = None
    speed: float = 0.0
    rot_speed: float = 0.0
    blend: float = 0.0

    @property
    def name(self) -> str:
        """Return the step as a short text, e.g. "lin pick"."""
        return f'{self.kind} {self.target.label}'


@dataclass(frozen=True)
class SpeedStep:
    """The joint speed fraction of the moves that follow (accelerations its square)."""

    fraction: float
    line: int

    @property
    def name(self) -> str:
        """Return the step as a short text."""
        return f'speed {self.fraction:g}'


@dataclass(frozen=True)
class GripperStep:
    """Open or close the gripper, and wait until it has."""

    action: str
    line: int

    @property
    def name(self) -> str:
        """Return the step as a short text."""
        return f'gripper {self.action}'


@dataclass(frozen=True)
class WaitStep:
    """
    Wait ``seconds``, or until digital input ``channel`` (1-based, /InputChannels) is ``state``.

    A wait for an input fails the program after ``timeout`` [s].
    """

    line: int
    seconds: float = 0.0
    channel: int = 0
    state: str = 'high'
    timeout: float = 0.0

    @property
    def name(self) -> str:
        """Return the step as a short text."""
        if self.channel:
            return f'wait input {self.channel} {self.state}'
        return f'wait {self.seconds:g} s'


@dataclass(frozen=True)
class RepeatStep:
    """Run ``steps`` ``count`` times."""

    count: int
    steps: tuple
    line: int

    @property
    def name(self) -> str:
        """Return the step as a short text."""
        return f'repeat {self.count}'


Step = Union[Move, SpeedStep, GripperStep, WaitStep, RepeatStep]


@dataclass(frozen=True)
class RunStep:
    """A step in the run order (repeats unrolled): its index, its step and its pass."""

    index: int
    step: Step
    passes: tuple       # the pass of each enclosing repeat (1-based), outermost first

    @property
    def name(self) -> str:
        """Return the step's name with its passes, e.g. "lin pick (pass 2/3)"."""
        return self.step.name


def unrolled(steps: tuple) -> list:
    """Return the ``RunStep`` list of ``steps``: repeats unrolled, indices from 0."""
    out = []

    def walk(items, passes):
        for step in items:
            if isinstance(step, RepeatStep):
                for k in range(step.count):
                    walk(step.steps, passes + (k + 1,))
            else:
                out.append(RunStep(len(out), step, passes))

    walk(steps, ())
    return out
