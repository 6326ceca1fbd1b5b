"""
End to end: a program run from the command line on the sim stack, and one refused.

The stack is the one of the stack definition (sim_bridge, controller, planner as processes);
``ros2 run mover6_control program`` runs as a user runs it, in a process of its own.
"""

import json
import subprocess

from mover6_control.resources import executable_command
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
from program_examples import pick_and_place, POINTS, write_program
import pytest
from ros_testing import GOAL_TOLERANCE, ready_client, SETTLE_TOLERANCE, Stack

pytestmark = pytest.mark.e2e

RUN_TIMEOUT = 180.0     # [s] the command line, startup, plan and ~10 s of motion


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start sim_bridge, controller and planner as processes for this module's tests."""
    with Stack(tmp_path_factory.mktemp('program_logs')) as running:
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a goal client node once every node answers (it reads /joint_states)."""
    with ready_client(stack, lambda: GoalClient(name='program_test'), timeout=30.0) as node:
        yield node


def program(*args):
    """Run the program command line; return the finished process."""
    return subprocess.run(executable_command('program') + [str(a) for a in args],
                          capture_output=True, text=True, timeout=RUN_TIMEOUT)


def fresh_q(client):
    """Return a /joint_states reading heard after this call."""
    client.q = None
    assert client.spin_until(lambda: client.q is not None, 10.0)
    return np.array(client.q)


def test_a_program_with_an_unreachable_step_is_refused_with_its_line(stack, client, tmp_path):
    """Its line and reason printed, exit 2, and the arm does not move (not even the first step)."""
    path = write_program(tmp_path, """\
        steps:
          - ptp: above_pick
          - lin: {pose: [1.5, 0.0, 0.2, 0.0, 1.5708, 0.0]}
        """)
    before = fresh_q(client)
    done = program('run', path)
    out = done.stdout + done.stderr
    assert done.returncode == 2, out + stack.report()
    assert f'refused: {path}:3: step 2 "lin pose' in out, out
    assert 'motion' not in out.split('refused')[-1]
    assert np.abs(fresh_q(client) - before).max() <= SETTLE_TOLERANCE, out


def test_the_pick_and_place_reaches_each_taught_point(stack, client, tmp_path):
    """Every motion ends SUCCESSFUL at its point within the goal tolerance; the arm holds there."""
    path = write_program(tmp_path, pick_and_place(repeat=1))
    report = tmp_path / 'report.json'
    done = program('run', path, '--report', report)
    out = done.stdout + done.stderr
    assert done.returncode == 0, out + stack.report()
    motions = json.loads(report.read_text())['motions']
    assert [m['target'] for m in motions] == ['above_pick', 'pick', 'place', 'above_place']
    for m in motions:
        assert m['ok'], m
        error = np.abs(np.array(m['q']) - POINTS[m['target']]).max()
        assert error <= GOAL_TOLERANCE, (m, out)
    held = fresh_q(client)
    assert np.abs(held - POINTS['above_place']).max() <= GOAL_TOLERANCE, out
