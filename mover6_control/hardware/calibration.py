"""
The first-run calibration file: what an operator confirmed of each joint, and its check.

``first_run`` (``mover6_control.tools.first_run``) jogs each joint +5 deg and back, and the
operator confirms the direction against the picture of the positive direction and, if measured,
the angle. It writes one YAML file:

    first_run: 2026-12-05T01:00:00Z
    joints_file: /path/to/mover6_joints.yaml
    joints:
      joint1: {gear: 528.2, sign_confirmed: true, scale_confirmed: true, ticks_moved: 1056,
               angle_moved_deg: 5.01, zero_offset_deg: null}

The driver reads it (parameter ``calibration_file``) and ``check_calibration`` compares it with
the joint file it drives with: a joint whose direction the operator saw wrong with the gear it
still has, or whose gear changed sign since a confirmed check, is an error (the driver refuses
to start: the arm would move mirrored); a gear whose size changed since, a joint never checked
or a scale not confirmed is a warning. Pure: no ROS, the file is read and written here.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
import math
from typing import Callable, Mapping, Optional, Sequence

from mover6_control.errors import InvalidInputError
from mover6_control.hardware.scaling import JointScale
import yaml


@dataclass(frozen=True)
class JointCalibration:
    """One joint's first-run result; ``None``: not measured or not asked."""

    gear: float
    sign_confirmed: Optional[bool]
    scale_confirmed: Optional[bool]
    ticks_moved: Optional[int]
    angle_moved_deg: Optional[float]
    zero_offset_deg: Optional[float] = None


def _optional(entry: Mapping, key: str, kind: type, where: str):
    value = entry.get(key)
    if value is None:
        return None
    if kind is bool and not isinstance(value, bool):
        raise InvalidInputError(f'{where}: {key} must be true, false or null, got {value!r}')
    if kind is not bool and (isinstance(value, bool) or not isinstance(value, (int, float))
                             or not math.isfinite(value)):
        raise InvalidInputError(f'{where}: {key} must be a finite number or null, '
                                f'got {value!r}')
    return kind(value)


def calibration_from_dict(data: Mapping) -> dict[str, JointCalibration]:
    """Return the joints of a calibration file's content; InvalidInputError on a bad entry."""
    joints = data.get('joints') if isinstance(data, Mapping) else None
    if not isinstance(joints, Mapping) or not joints:
        raise InvalidInputError('a calibration file has a mapping "joints" of joint names')
    out = {}
    for name, entry in joints.items():
        where = f'calibration of {name}'
        if not isinstance(entry, Mapping):
            raise InvalidInputError(f'{where}: a mapping, got {entry!r}')
        gear = _optional(entry, 'gear', float, where)
        if gear is None or gear == 0.0:
            raise InvalidInputError(f'{where}: gear (the one the check ran with) is required')
        out[str(name)] = JointCalibration(
            gear, _optional(entry, 'sign_confirmed', bool, where),
            _optional(entry, 'scale_confirmed', bool, where),
            _optional(entry, 'ticks_moved', int, where),
            _optional(entry, 'angle_moved_deg', float, where),
            _optional(entry, 'zero_offset_deg', float, where))
    return out


def load_calibration(path: str) -> dict[str, JointCalibration]:
    """Read a calibration file; InvalidInputError, with the reason, if it cannot be used."""
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as err:
        raise InvalidInputError(f'calibration_file {path!r} cannot be read: {err}') from None
    return calibration_from_dict(data)


def write_calibration(path: str, joints: Mapping[str, JointCalibration], stamp: str,
                      joints_file: str) -> None:
    """Write ``joints`` to ``path`` with the time ``stamp`` and the joint file it ran with."""
    data = {'first_run': stamp, 'joints_file': joints_file,
            'joints': {name: asdict(c) for name, c in joints.items()}}
    with open(path, 'w') as f:
        yaml.safe_dump(data, f, sort_keys=False)


def check_calibration(calibration: Mapping[str, JointCalibration],
                      joints: Sequence[JointScale]) -> tuple[list[str], list[str]]:
    """Return ``(errors, warnings)`` of driving ``joints`` with ``calibration`` (docstring)."""
    errors, warnings = [], []
    for j in joints:
        c = calibration.get(j.name)
        if c is None or c.sign_confirmed is None:
            warnings.append(f'{j.name}: no direction checked by first_run')
            continue
        same_sign = (c.gear > 0) == (j.gear > 0)
        if c.sign_confirmed and not same_sign:
            errors.append(f'{j.name}: its gear changed sign ({c.gear:g} -> {j.gear:g}) since '
                          'first_run confirmed its direction: the joint would turn the other '
                          'way; run first_run again')
        elif not c.sign_confirmed and same_sign:
            errors.append(f'{j.name}: first_run saw it turn against its positive direction '
                          f'with gear {c.gear:g}, which it still has: flip the sign of its '
                          'gear in the joint file, then run first_run again')
        elif not c.sign_confirmed:
            warnings.append(f'{j.name}: gear sign flipped since first_run saw it wrong: run '
                            'first_run again to confirm')
        if abs(abs(c.gear) - abs(j.gear)) > 1e-9 * abs(j.gear):
            warnings.append(f'{j.name}: gear {j.gear:g}, first_run ran with {c.gear:g}')
        if c.scale_confirmed is False:
            warnings.append(f'{j.name}: the angle moved was not confirmed (scale: measure a '
                            'known angle)')
    return errors, warnings


def calibration_refusal(path: str, joints: Sequence[JointScale],
                        warn: Callable[[str], None]) -> str:
    """
    Return why the driver may not start with the calibration file ``path`` ('' when it may).

    An empty ``path`` warns that no first-run check is on record; each warning goes to ``warn``.
    """
    if not path:
        warn("no calibration_file: the joints' directions are not confirmed (run first_run)")
        return ''
    try:
        errors, warnings = check_calibration(load_calibration(path), joints)
    except InvalidInputError as err:
        return str(err)
    for text in warnings:
        warn(f'calibration: {text}')
    return '; '.join(errors)
