"""launch.sh reads the node roles' table through the launch shell's output (a process)."""

import os
import subprocess
import sys

from mover6_control import node_roles
from mover6_control.node_roles import ESSENTIAL, RESTART_DELAY
from mover6_control.resources import CONFIG_DIR


def test_launch_sh_reads_the_table():
    """launch.sh evaluates the launch shell's output: the same names and delays."""
    out = subprocess.run([sys.executable, '-m', 'mover6_control.node_roles', 'shell'],
                         capture_output=True, text=True, check=True,
                         cwd=os.path.dirname(CONFIG_DIR)).stdout
    assert out == node_roles.shell()
    assert f"ESSENTIAL='{' '.join(ESSENTIAL)}'" in out and f'RESTART_DELAY={RESTART_DELAY}' in out
    with open(os.path.join(os.path.dirname(CONFIG_DIR), 'scripts', 'launch.sh')) as f:
        script = f.read()
    assert 'python3 -m mover6_control.tools.launch_shell -- "$@"' in script
    setup = subprocess.run([sys.executable, '-m', 'mover6_control.tools.launch_shell', '--'],
                           capture_output=True, text=True, check=True,
                           cwd=os.path.dirname(CONFIG_DIR)).stdout
    assert node_roles.shell() in setup
    assert '" $HELPERS "' in script
