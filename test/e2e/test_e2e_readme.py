"""
End to end: the README's parabolic goal line, typed as written, from home through the three nodes.

The README's "Sending goals" line with ``--motion parabolic`` is read from the README and run
through the goal command as its own process, right after ``sim_bridge``'s ~/reset (home, where
every start-up begins); it must exit 0.
"""

import os
import shlex
import subprocess
import sys

from mover6_control.resources import CONFIG_DIR
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
from readme_goals import goal_argv, readme_goal_lines
from ros_testing import ready_client, Stack
from std_srvs.srv import Trigger

pytestmark = pytest.mark.e2e


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start sim_bridge, controller and planner as processes for this module's tests."""
    with Stack(tmp_path_factory.mktemp('e2e_readme_logs')) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a goal client in this process once every node answers."""
    with ready_client(stack, lambda: GoalClient(name='e2e_readme_client')) as node:
        yield node


def run_readme_line_from_home(stack, client, mark):
    """Reset the arm to home, run the README's one goal line with ``mark``; return its argv."""
    lines = [line for line in readme_goal_lines() if mark in line]
    assert len(lines) == 1, lines
    argv = goal_argv(lines[0])
    reset = client.create_client(Trigger, 'sim_bridge/reset')
    assert reset.wait_for_service(timeout_sec=10.0), stack.report()
    future = reset.call_async(Trigger.Request())
    assert client.spin_until(future.done, 10.0) and future.result().success, stack.report()
    assert client.spin_until(
        lambda: client.q is not None and np.abs(client.q).max() < 1e-3, 10.0), client.q
    proc = subprocess.run([sys.executable, '-m', 'mover6_control.tools.goal_cli',
                           *argv, '--timeout', '60'],
                          capture_output=True, text=True, timeout=120,
                          cwd=os.path.dirname(CONFIG_DIR))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f'{shlex.join(argv)}\n{out}\n{stack.report()}'
    assert 'RESULT arrived' in out, out
    return argv


def test_readme_parabolic_goal_arrives_from_home(stack, client):
    """The README's parabolic line after a reset to home: exit 0 and RESULT arrived."""
    run_readme_line_from_home(stack, client, '--motion parabolic')


@pytest.mark.parametrize('mark', ['--shape joint', '--profile'])
def test_readme_via_joint_and_profile_goals_arrive_from_home(stack, client, mark):
    """The README's via-point joint move and its per-goal profile line, from home: exit 0."""
    argv = run_readme_line_from_home(stack, client, mark)
    if mark == '--profile':
        # The controller timed that motion with the goal's law; its parameter is unchanged.
        profile = argv[argv.index('--profile') + 1]
        client.spin_until(lambda: client.values(client.controller_status).get(
            'motion_profile') == profile, 5.0)
        values = client.values(client.controller_status)
        assert values.get('motion_profile') == profile, values
        assert values.get('profile') == 'continuous', values
