"""
A demand's waypoints go into the message as one float32 buffer (issue 32, round 3).

The same bytes as the message's own setter makes of a list of Python floats (each rounded to
float32), read back the same; a value the setter refuses is refused as before.
"""

import array

from mover6_control.nodes.messages import demand_messages
import numpy as np
import pytest
from std_msgs.msg import Float32MultiArray


def through_the_setter(Q):
    """Return the message data the setter makes of ``Q`` as a list of floats."""
    msg = Float32MultiArray()
    msg.data = [float(x) for x in np.asarray(Q, dtype=float).ravel()]
    return msg.data


@pytest.mark.parametrize('Q', [
    np.random.default_rng(32).normal(0.0, 2.0, (1000, 6)),
    np.array([[np.nan, np.inf, -np.inf, 1e-46, 3.4e38, -1e-40]]),
    np.array([[1e39, -1e300, 3.4028235e38, 0.1, -0.0, 2.0 ** -149]]),
    np.zeros((1, 6)),
], ids=['1000 waypoints', 'non-finite and tiny', 'beyond float32', 'one row'])
def test_the_buffer_holds_the_bytes_the_setter_makes(Q):
    data = demand_messages.make_demands(Q, 'g', 'cubic').data
    assert isinstance(data, array.array) and data.typecode == 'f'
    assert data.tobytes() == through_the_setter(Q).tobytes()


def test_waypoints_read_back_as_float32_values_in_their_layout():
    Q = np.random.default_rng(7).uniform(-2.0, 2.0, (100, 6))
    msg = demand_messages.make_demands(Q, 'g-7')
    back = demand_messages.demands_from_msg(msg, 6)
    np.testing.assert_array_equal(back, Q.astype(np.float32).astype(float))
    assert demand_messages.demand_id_from_msg(msg) == 'g-7'
    assert [d.size for d in msg.layout.dim] == [100, 6]
