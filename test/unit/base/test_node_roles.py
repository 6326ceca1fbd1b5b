"""
The one table of essential and helper nodes, and the helpers' back-off (node_roles).

launch.sh's reading of it (a process): test/e2e/test_node_roles_shell.py.
"""

from mover6_control.node_roles import (ESSENTIAL, HELPERS, is_essential, MAX_RESTART_DELAY,
                                       RESTART_DELAY, restart_delay)
import pytest


def test_essential_and_helpers_are_apart_and_named():
    assert not set(ESSENTIAL) & set(HELPERS)
    assert is_essential('controller') and is_essential('sim_bridge') and is_essential('driver')
    assert not is_essential('markers') and not is_essential('planner')
    with pytest.raises(KeyError, match='neither'):
        is_essential('no_such_node')


def test_the_delay_doubles_up_to_its_limit():
    delays = [restart_delay(n) for n in range(8)]
    assert delays[:3] == [RESTART_DELAY, 2 * RESTART_DELAY, 4 * RESTART_DELAY]
    assert delays[-1] == MAX_RESTART_DELAY and max(delays) == MAX_RESTART_DELAY
    assert delays == sorted(delays)
