"""
The /joint_demands messages: waypoints (N x 6) in a Float32MultiArray, and the label's options.

A demand's first dimension is labelled ``waypoints``, then any of ``goal <id>`` and ``profile
<name>``: the goal it was planned for and the controller's law for it alone (``make_demands``
writes them, ``demand_options_from_msg`` reads them back). ``demand_from_msg`` validates once
into a ``values.JointDemand`` and raises ``InvalidInputError`` with a reason a person can read
and a code, as every ``*_from_msg`` of ``nodes/messages/conversions.py``.
"""

import array

from mover6_control.errors import InvalidInputError, ShapeError
from mover6_control.values import JointDemand
import numpy as np
from std_msgs.msg import Float32MultiArray, MultiArrayDimension

# The largest magnitude the message's float32 field takes (its setter's own bound).
FLOAT32_BOUND = 3.402823466e+38


def demand_from_msg(msg: Float32MultiArray, n_joints: int = 6) -> JointDemand:
    """
    Return the ``JointDemand`` (n, n_joints) [rad] of a Float32MultiArray, checked once.

    Accepts the layout ``make_demands`` writes (dim[0] waypoints, dim[1] joints) or a flat
    array with no layout whose length is a multiple of ``n_joints`` (the Mover6 report's MATLAB
    and terminal usage). Raises ``InvalidInputError`` with its code (``errors.INPUT_CODES``).
    """
    dims = list(msg.layout.dim)
    data = msg.data
    if dims and len(data):
        if len(dims) != 2:
            raise ShapeError(f'joint demands layout must have 2 dims, got {len(dims)}')
        n, m = dims[0].size, dims[1].size
        if m != n_joints:
            raise ShapeError(f'joint demands have {m} joints per row, expected {n_joints}')
        if n * m != len(data) - msg.layout.data_offset:
            raise ShapeError(
                f'joint demands layout says {n} x {m} but data has {len(data)} values')
        data = data[msg.layout.data_offset:]
    return JointDemand.from_rows(np.asarray(data, dtype=float), n_joints)


def demands_from_msg(msg: Float32MultiArray, n_joints: int = 6) -> np.ndarray:
    """Return the waypoints (n, n_joints) [rad] of ``demand_from_msg``: a read-only array."""
    return demand_from_msg(msg, n_joints).positions


DEMAND_LABEL = 'waypoints'
DEMAND_ID_MARK = ' goal '
DEMAND_OPTIONS = ('goal', 'profile')   # the words of a demand label, each with one value


def make_demands(Q: np.ndarray, goal_id: str = '', profile: str = '') -> Float32MultiArray:
    """
    Build a Float32MultiArray (with layout) from waypoints (n, 6) [rad].

    A ``goal_id`` goes into the first dimension's label, ``waypoints goal <goal_id>``, where
    ``ros2 topic echo`` shows it; ``demand_id_from_msg`` reads it back. A ``profile`` (the
    controller's law for this demand only) follows: ``waypoints goal <goal_id> profile cubic``
    (``demand_profile_from_msg``).
    """
    Q = np.asarray(Q, dtype=float)
    n, m = Q.shape
    msg = Float32MultiArray()
    label = DEMAND_LABEL + (DEMAND_ID_MARK + goal_id if goal_id else '')
    label += f' profile {profile}' if profile else ''
    msg.layout.dim = [
        MultiArrayDimension(label=label, size=n, stride=n * m),
        MultiArrayDimension(label='joints', size=m, stride=m),
    ]
    flat = Q.ravel()
    finite = flat[np.isfinite(flat)]
    if finite.size and np.abs(finite).max() > FLOAT32_BOUND:
        msg.data = [float(x) for x in flat]     # the setter refuses it (AssertionError)
    else:
        # One buffer copy, rounded to float32 as the setter would round each float (a list
        # of 6,000 Python floats cost 0.5 ms at 1,000 waypoints).
        msg.data = array.array('f', flat.astype(np.float32).tobytes())
    return msg


def demand_options_from_msg(msg: Float32MultiArray) -> dict:
    """
    Return the options of a demand's label as a dict (``goal``, ``profile``; absent: not given).

    The label is ``waypoints``, then any of ``goal <id>`` and ``profile <name>`` in any order
    (typable in ``ros2 topic pub``). A demand without layout or with another label carries no
    options (the Mover6 report's flat arrays). Raises ``InvalidInputError`` for a word without
    a value, an unknown word or a word given twice.
    """
    dims = list(msg.layout.dim)
    words = (dims[0].label if dims else '').split()
    if not words or words[0] != DEMAND_LABEL:
        return {}
    options = {}
    for key, value in zip(words[1::2], words[2::2] + [None]):
        if key not in DEMAND_OPTIONS or value is None or key in options:
            raise InvalidInputError(
                f'demand label "{dims[0].label}": expected "waypoints [goal <id>] '
                f'[profile <name>]"')
        options[key] = value
    return options


def demand_id_from_msg(msg: Float32MultiArray) -> str:
    """Return the goal id a demand carries (``make_demands``), '' when it carries none."""
    try:
        return demand_options_from_msg(msg).get('goal', '')
    except InvalidInputError:
        return ''


def demand_profile_from_msg(msg: Float32MultiArray) -> str:
    """Return the profile a demand asks for, '' for the controller's; raises on a bad label."""
    return demand_options_from_msg(msg).get('profile', '')
