"""The one validator module: finite arrays of a shape, positive numbers and positive vectors."""

from mover6_control.errors import InvalidInputError
from mover6_control.validation import as_finite_array, as_positive
import numpy as np
import pytest


def test_finite_array_of_a_shape():
    arr = as_finite_array([[1, 2, 3]], (None, 3), 'Q')
    assert arr.dtype == float and arr.shape == (1, 3)
    with pytest.raises(InvalidInputError, match='shape'):
        as_finite_array([1.0, 2.0], (3,), 'q')
    with pytest.raises(InvalidInputError, match='non-finite'):
        as_finite_array([1.0, np.inf], (None,), 'q')
    with pytest.raises(InvalidInputError, match='numeric'):
        as_finite_array('abc', (), 'x')


def test_positive_number():
    assert as_positive(2, 'rate') == 2.0 and isinstance(as_positive(2, 'rate'), float)
    assert as_positive(None, 'max_condition', allow_none=True) is None
    for bad in (0.0, -1.0, float('nan'), float('inf')):
        with pytest.raises(InvalidInputError, match='rate must be positive'):
            as_positive(bad, 'rate')
    with pytest.raises(InvalidInputError, match='number'):
        as_positive('fast', 'rate')
    with pytest.raises(InvalidInputError):
        as_positive(None, 'rate')


def test_positive_vector_broadcasts_a_scalar_and_checks_the_shape():
    np.testing.assert_array_equal(as_positive(0.5, 'v_max', 3), [0.5, 0.5, 0.5])
    limits = np.array([1.0, 2.0])
    out = as_positive(limits, 'v_max', 2)
    np.testing.assert_array_equal(out, limits)
    assert out is not limits                                     # a new array: safe to scale
    assert as_positive(1.0, 'a_max', 2, allow_none=True).shape == (2,)
    assert as_positive(None, 'a_max', 2, allow_none=True) is None
    with pytest.raises(InvalidInputError, match='shape'):
        as_positive([1.0, 2.0], 'v_max', 3)
    with pytest.raises(InvalidInputError, match='positive'):
        as_positive([1.0, 0.0], 'v_max', 2)
    with pytest.raises(InvalidInputError, match='non-finite'):
        as_positive([1.0, np.nan], 'v_max', 2)
