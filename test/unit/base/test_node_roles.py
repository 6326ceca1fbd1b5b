"""The one table of essential and helper nodes, and the helpers' back-off (node_roles)."""

import os
import subprocess
import sys

from mover6_control import node_roles
from mover6_control.node_roles import (ESSENTIAL, HELPERS, is_essential, MAX_RESTART_DELAY,
                                       RESTART_DELAY, restart_delay)
from mover6_control.resources import CONFIG_DIR
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


def test_launch_sh_reads_the_table():
    """launch.sh evaluates the module's shell output: the same names and delays."""
    out = subprocess.run([sys.executable, '-m', 'mover6_control.node_roles', 'shell'],
                         capture_output=True, text=True, check=True,
                         cwd=os.path.dirname(CONFIG_DIR)).stdout
    assert out == node_roles.shell()
    assert f"ESSENTIAL='{' '.join(ESSENTIAL)}'" in out and f'RESTART_DELAY={RESTART_DELAY}' in out
    with open(os.path.join(os.path.dirname(CONFIG_DIR), 'scripts', 'launch.sh')) as f:
        script = f.read()
    assert 'python3 -m mover6_control.node_roles shell' in script
    assert '" $HELPERS "' in script
