"""
Input validation shared by every layer: finite arrays of a shape, positive numbers and vectors.

A base module (like ``errors``): it imports nothing of this package but ``errors``, so the
kinematics, motion and control layers all check their inputs the same way and raise
``InvalidInputError`` with the argument's name.
"""

from __future__ import annotations

from typing import Optional, Sequence

from mover6_control.errors import InvalidInputError, NonFiniteError, ShapeError
import numpy as np


def as_finite_array(value: object, shape: Sequence[Optional[int]], name: str) -> np.ndarray:
    """
    Return ``value`` as a float array of ``shape`` or raise a helpful error.

    ``shape`` may hold ``None`` for an axis of any length.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise ShapeError(f'{name} must be numeric, got {value!r}') from err
    if arr.ndim != len(shape) or any(
            want is not None and got != want for got, want in zip(arr.shape, shape)):
        want = tuple('n' if s is None else s for s in shape)
        raise ShapeError(f'{name} must have shape {want}, got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f'{name} has non-finite values: {arr.tolist()}')
    return arr


def as_positive(value: object, name: str, n: Optional[int] = None, *,
                allow_none: bool = False) -> float | np.ndarray | None:
    """
    Return ``value`` checked to be positive and finite: a float, or with ``n`` an array (n,).

    Without ``n`` the value is one number (a setting such as a tolerance or a time [s]). With
    ``n`` it is a per-joint limit: a scalar is broadcast to (n,), anything else must have shape
    (n,); the result is a new float array. ``allow_none`` lets None through (an optional
    setting) and returns None.
    """
    if value is None and allow_none:
        return None
    if n is None:
        try:
            number = float(value)
        except (TypeError, ValueError) as err:
            raise ShapeError(f'{name} must be a number, got {value!r}') from err
        if not np.isfinite(number):
            raise NonFiniteError(f'{name} must be positive and finite, got {number}')
        if number <= 0.0:
            raise InvalidInputError(f'{name} must be positive and finite, got {number}',
                                    'out_of_range')
        return number
    if np.ndim(value) == 0:
        arr = np.full(int(n), float(as_finite_array(value, (), name)))
    else:
        arr = np.array(as_finite_array(value, (n,), name), dtype=float)
    if np.any(arr <= 0.0):
        raise InvalidInputError(f'{name} must be positive and finite, got {arr.tolist()}',
                                'out_of_range')
    return arr


# [characters] the longest reason sent out again (a status, a result, a set-parameters answer).
MAX_REASON = 500


def short_text(text: str, most: int = MAX_REASON) -> str:
    """
    Return ``text`` cut to at most ``most`` characters, saying how long it was.

    A reason that quotes hostile input (a huge list, thousands of waypoints) stays small where
    it goes out again: a status, a set-parameters answer, a log line.
    """
    text = str(text)
    if len(text) <= most:
        return text
    tail = f'... ({len(text)} characters)'
    return text[:max(most - len(tail), 0)] + tail
