"""
Joint scaling of the Mover6: joint angles [rad] <-> motor encoder ticks, limits in ticks.

One joint: ``ticks = rad x gear x ticks_per_rev / (2 pi)``, rounded to the nearest tick (so a
round trip rad -> ticks -> rad is within half a tick; the vendor's ``Joint::PositionToTicks``
truncates towards zero instead, up to a whole tick off). On the wire a module gets and reports
``ticks + offset``. Limits are kept in ticks, clamping there: with a negative gear the lower
joint limit is the upper tick limit (the vendor's ``MotorModule::set_DesiredPosition`` swaps
them the same way), and each tick limit is rounded inwards, so a clamped set-point is never
outside the joint's limit. A limit set's range is always intersected with the 'hardware' one:
no set can widen the vendor's software limits.

The numbers live in ``config/mover6_joints.yaml`` (gear with its sign, ticks per motor turn,
offset, limits per set, max speed), from the vendor's ``CPRMover6.cpp`` and ``Joint.cpp``
(farshad-heravi/cpr_robot, jonaitken/cpr_ros2).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import os
from typing import Mapping

from mover6_control.errors import InvalidInputError
from mover6_control.hardware.protocol import ERROR_FLAGS
from mover6_control.resources import CONFIG_DIR
import yaml

JOINTS_YAML = os.path.join(CONFIG_DIR, 'mover6_joints.yaml')
HARDWARE = 'hardware'


@dataclass(frozen=True)
class JointScale:
    """
    One joint's scaling: ``gear`` (signed), ``ticks_per_rev`` per motor turn, ``offset`` [ticks].

    ``limits`` maps a limit set's name to (lower, upper) [rad]; ``max_speed`` [rad/s].
    ``reference_required``: no motion while the module is not referenced; ``reference_order``:
    joints are referenced one at a time, lowest first (ties in module order).
    """

    name: str
    module: int
    gear: float
    ticks_per_rev: int
    offset: int
    limits: Mapping[str, tuple[float, float]]
    max_speed: float
    reference_required: bool = False
    reference_order: int = 0

    @property
    def ticks_per_rad(self) -> float:
        """Return the encoder ticks per joint radian, signed like the gear [ticks/rad]."""
        return self.gear * self.ticks_per_rev / (2.0 * math.pi)

    @property
    def tick(self) -> float:
        """Return one encoder tick as a joint angle [rad] (positive)."""
        return 1.0 / abs(self.ticks_per_rad)

    def to_ticks(self, q: float) -> int:
        """Return joint angle ``q`` [rad] as the nearest encoder tick (offset not included)."""
        if not math.isfinite(q):
            raise InvalidInputError(f'{self.name}: angle must be finite, got {q!r}')
        return int(round(q * self.ticks_per_rad))

    def to_rad(self, ticks: int) -> float:
        """Return encoder ``ticks`` (offset not included) as a joint angle [rad]."""
        return ticks / self.ticks_per_rad

    def to_wire(self, ticks: int) -> int:
        """Return ``ticks`` as the module sees them: plus the offset."""
        return int(ticks) + self.offset

    def from_wire(self, position: int) -> int:
        """Return a module's position as joint ticks: minus the offset."""
        return int(position) - self.offset

    def limits_rad(self, limit_set: str = HARDWARE) -> tuple[float, float]:
        """Return (lower, upper) [rad] of ``limit_set``, intersected with the hardware limits."""
        if limit_set not in self.limits:
            raise InvalidInputError(f'limit_set must be one of {sorted(self.limits)}, '
                                    f'got {limit_set!r}')
        lo, hi = self.limits[limit_set]
        hw_lo, hw_hi = self.limits[HARDWARE]
        return max(lo, hw_lo), min(hi, hw_hi)

    def tick_limits(self, limit_set: str = HARDWARE) -> tuple[int, int]:
        """Return (min, max) [ticks] of ``limit_set``, rounded inwards (swapped for gear < 0)."""
        a, b = (q * self.ticks_per_rad for q in self.limits_rad(limit_set))
        lo, hi = min(a, b), max(a, b)
        # A hair of slack so a limit that is an exact tick is not rounded a tick inwards.
        return math.ceil(lo - 1e-9), math.floor(hi + 1e-9)

    def clamp_ticks(self, ticks: int, limit_set: str = HARDWARE) -> int:
        """Return ``ticks`` clamped into the tick limits of ``limit_set``."""
        lo, hi = self.tick_limits(limit_set)
        return min(max(int(ticks), lo), hi)


def _number(entry: Mapping, key: str, where: str) -> float:
    value = entry.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise InvalidInputError(f'{where}: {key} must be a finite number, got {value!r}')
    return float(value)


def _integer(entry: Mapping, key: str, where: str) -> int:
    value = entry.get(key)
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidInputError(f'{where}: {key} must be an integer, got {value!r}')
    return value


def joint_from_dict(entry: Mapping, where: str = 'joint') -> JointScale:
    """Return one joint's scaling from its YAML entry (limits [deg], max_speed [deg/s])."""
    if not isinstance(entry, Mapping):
        raise InvalidInputError(f'{where} must be a mapping, got {entry!r}')
    name = entry.get('name')
    if not isinstance(name, str) or not name:
        raise InvalidInputError(f'{where}: name must be a non-empty string, got {name!r}')
    where = f'{where} ({name})'
    gear = _number(entry, 'gear', where)
    ticks = _integer(entry, 'ticks_per_rev', where)
    speed = _number(entry, 'max_speed', where)
    if gear == 0.0 or ticks <= 0 or speed <= 0.0:
        raise InvalidInputError(f'{where}: gear must be non-zero, ticks_per_rev and max_speed '
                                f'positive, got {gear}, {ticks}, {speed}')
    raw = entry.get('limits')
    if not isinstance(raw, Mapping) or HARDWARE not in raw:
        raise InvalidInputError(f'{where}: limits must map limit sets, "{HARDWARE}" among '
                                f'them, to [lower, upper] [deg], got {raw!r}')
    limits = {}
    for set_name, pair in raw.items():
        if not isinstance(pair, (list, tuple)) or len(pair) != 2 or \
                not all(isinstance(v, (int, float)) and math.isfinite(v) for v in pair) or \
                not pair[0] < pair[1]:
            raise InvalidInputError(f'{where}: limits.{set_name} must be [lower, upper] [deg] '
                                    f'with lower < upper, got {pair!r}')
        limits[str(set_name)] = (math.radians(pair[0]), math.radians(pair[1]))
    required, order = _referencing(entry.get('referencing'), where)
    return JointScale(name=name, module=_integer(entry, 'module', where), gear=gear,
                      ticks_per_rev=ticks, offset=_integer(entry, 'offset', where),
                      limits=limits, max_speed=math.radians(speed),
                      reference_required=required, reference_order=order)


def _referencing(raw, where: str) -> tuple[bool, int]:
    """Return (required, order) from a joint's ``referencing`` entry (absent: not required)."""
    if raw is None:
        return False, 0
    if not isinstance(raw, Mapping) or not isinstance(raw.get('required'), bool) or \
            set(raw) - {'required', 'order'}:
        raise InvalidInputError(f'{where}: referencing must be {{required: true|false, '
                                f'order: N}}, got {raw!r}')
    order = raw.get('order', 0)
    if isinstance(order, bool) or not isinstance(order, int) or order < 0:
        raise InvalidInputError(f'{where}: referencing.order must be an integer >= 0, '
                                f'got {order!r}')
    return raw['required'], order


def joints_from_dict(data: Mapping) -> tuple[str, tuple[JointScale, ...]]:
    """Return (firmware, joints) from the parsed YAML of ``mover6_joints.yaml``."""
    if not isinstance(data, Mapping) or not isinstance(data.get('joints'), list) or \
            not data['joints']:
        raise InvalidInputError('the joint file must hold a non-empty list "joints"')
    joints = tuple(joint_from_dict(e, f'joints[{i}]') for i, e in enumerate(data['joints']))
    modules = [j.module for j in joints]
    if sorted(modules) != list(range(1, len(joints) + 1)):
        raise InvalidInputError(f'joint modules must be 1..{len(joints)} once each, got '
                                f'{modules}')
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        raise InvalidInputError(f'joint names must be unique, got {names}')
    sets = {frozenset(j.limits) for j in joints}
    if len(sets) != 1:
        raise InvalidInputError('every joint must have the same limit sets')
    firmware = data.get('firmware', 'mover6')
    if firmware not in ERROR_FLAGS:
        raise InvalidInputError(f'firmware must be one of {sorted(ERROR_FLAGS)}, '
                                f'got {firmware!r}')
    return firmware, joints


def load_joints(path: str = JOINTS_YAML) -> tuple[str, tuple[JointScale, ...]]:
    """Read a joint file (default: the shipped Mover6's) and return (firmware, joints)."""
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as err:
        raise InvalidInputError(f'cannot read the joint file {path!r}: {err}') from err
    return joints_from_dict(data)
