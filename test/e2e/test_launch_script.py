"""
scripts/launch.sh: starts the three nodes, and stops all of them when one dies or on Ctrl-C.

Needs the package built and on the ament index (./run.sh test does that).
"""

import os
import re
import signal
import subprocess
import time

from mover6_control.resources import CONFIG_DIR
import pytest
from ros_testing import installed, pid_alive

pytestmark = pytest.mark.e2e

SCRIPT = os.path.join(os.path.dirname(CONFIG_DIR), 'scripts', 'launch.sh')
# What a plain launch.sh (the simulator) starts.
STARTED = {'sim_bridge', 'controller', 'planner', 'state_publisher', 'markers'}


def wait_for(predicate, timeout):
    """Poll ``predicate`` until it holds or ``timeout`` [s] passes; return it."""
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.1)
    return predicate()


def start(tmp_path):
    """Start launch.sh; return (process, path of its stderr log)."""
    log = tmp_path / 'launch.err'
    proc = subprocess.Popen(['bash', SCRIPT, '--log-dir', str(tmp_path / 'logs')],
                            stdout=subprocess.DEVNULL, stderr=open(log, 'w'),
                            start_new_session=True)
    return proc, log


def node_pids(log, count=None, timeout=30.0):
    """Return {node: pid} from launch.sh's 'started' lines once ``count`` nodes started."""
    found = {}
    count = len(STARTED) if count is None else count

    def enough():
        found.update(re.findall(r'started (\w+) \(pid (\d+)\)', log.read_text()))
        return len(found) >= count
    assert wait_for(enough, timeout), log.read_text()
    return {name: int(pid) for name, pid in found.items()}


@pytest.mark.skipif(not installed(), reason='needs the built package (./run.sh test)')
def test_one_node_dying_stops_the_others(tmp_path):
    """Kill the controller: launch.sh stops the other nodes and exits non-zero."""
    proc, log = start(tmp_path)
    try:
        pids = node_pids(log)
        assert set(pids) == STARTED
        assert all(pid_alive(p) for p in pids.values())
        os.kill(pids['controller'], signal.SIGKILL)
        assert proc.wait(30) != 0
        assert wait_for(lambda: not any(pid_alive(p) for p in pids.values()), 15.0)
        assert 'controller exited' in log.read_text()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


@pytest.mark.skipif(not installed(), reason='needs the built package (./run.sh test)')
def test_ctrl_c_stops_every_node(tmp_path):
    """SIGINT to launch.sh (Ctrl-C) stops every node it started."""
    proc, log = start(tmp_path)
    try:
        pids = node_pids(log)
        # Let the nodes come up fully before interrupting.
        assert wait_for(lambda: (tmp_path / 'logs' / 'planner.log').exists()
                        and 'planner ready' in (tmp_path / 'logs' / 'planner.log').read_text(),
                        30.0)
        proc.send_signal(signal.SIGINT)
        proc.wait(30)
        assert wait_for(lambda: not any(pid_alive(p) for p in pids.values()), 15.0)
        assert 'all nodes stopped' in log.read_text()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


@pytest.mark.skipif(not installed(), reason='needs the built package (./run.sh test)')
def test_a_helper_that_dies_is_started_again_and_the_motion_arrives(tmp_path):
    """
    Kill each helper in turn (by pid, SIGKILL) while the arm moves: the motion arrives.

    launch.sh reports the helper's exit and starts it again after its back-off delay
    (mover6_control/node_roles.py); the sim bridge and the controller are never restarted, and
    the planner, started again, plans the next goal.
    """
    import numpy as np
    import rclpy
    from mover6_control.kinematics.forward import fk
    from mover6_control.node_roles import HELPERS
    from mover6_control.tools.goal_cli import GoalClient
    proc, log = start(tmp_path)
    rclpy.init()
    client = None
    try:
        pids = node_pids(log)
        client = GoalClient(name='helper_killer')
        problem = client.wait_ready(timeout=60.0)
        assert problem is None, f'{problem}\n{log.read_text()}'
        helpers = [n for n in sorted(STARTED) if n in HELPERS]
        assert helpers == ['markers', 'planner', 'state_publisher']

        def planner_goal_readers():
            return {bytes(i.endpoint_gid) for i in client.get_subscriptions_info_by_topic(
                '/pose_goal') if i.node_name == 'planner'}
        first_planner = planner_goal_readers()
        for k, name in enumerate(helpers):
            killed = []

            def kill_once(_, name=name, killed=killed):
                if not killed:
                    killed.append(node_pids(log)[name])
                    os.kill(killed[0], signal.SIGKILL)
            q = np.full(6, 0.3 if k % 2 == 0 else -0.3)
            outcome = client.send_joints([q], progress=kill_once, timeout=60.0)
            assert killed, f'{name}: the motion ended before it could be killed'
            assert outcome.arrived, f'{name} killed: {outcome}\n{log.read_text()}'
            assert wait_for(lambda: node_pids(log)[name] != killed[0], 30.0), log.read_text()
            assert pid_alive(node_pids(log)[name])
            assert f'{name} exited (code' in log.read_text()
        text = log.read_text()
        assert 'stopping the others' not in text and proc.poll() is None, text
        for name in ('sim_bridge', 'controller'):
            assert node_pids(log)[name] == pids[name] and pid_alive(pids[name]), text
        # The planner started again plans: a pose goal through it arrives.
        assert client.spin_until(lambda: client.values(client.planner_status).get('state')
                                 == 'ready', 60.0), client.planner_status
        # The new planner's reader is in the graph (a reader the first planner did not have:
        # a killed one stays listed until its lease ends) and the goal's writer matched every
        # reader the graph shows: a goal sent before that would be lost on the way.
        assert client.spin_until(lambda: planner_goal_readers() - first_planner, 60.0), \
            'the new planner never subscribed /pose_goal'
        assert client.spin_until(lambda: client.pose_pub.get_subscription_count() >= len(
            client.get_subscriptions_info_by_topic('/pose_goal')) >= 2, 60.0)
        outcome = client.send_pose(fk(client.arm, np.full(6, 0.1)), timeout=60.0)
        assert outcome.arrived, f'{outcome}\n{log.read_text()}'
    finally:
        if client is not None:
            client.destroy_node()
        rclpy.try_shutdown()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
