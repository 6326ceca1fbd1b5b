"""
End to end, at start-up: a goal sent before the nodes have seen any joint state still arrives.

Issue 21: a goal sent as soon as the planner existed was refused ("no /joint_states received
yet"), or planned and then refused by a controller that had no states yet, with nothing said.
Here the planner starts alone, the goal goes to it, and only then do the sim bridge and the
controller start; and the goal command line runs right after the launcher starts.
"""

import os
import re
import signal
import subprocess

from geometry_msgs.msg import PoseStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.messages import conversions
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
import rclpy
from ros_testing import installed, Stack, wait_until
from source_tree import ROOT

pytestmark = pytest.mark.e2e

ARM = mover6()
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
# [s] the planner's wait for states: the bridge and the controller start after the goal, and a
# loaded machine can take many seconds for that (the default is 5 s).
STATE_WAIT = 60.0


@pytest.fixture
def client():
    """Return a goal client in this process."""
    rclpy.init()
    node = GoalClient(name='startup_client')
    yield node
    node.destroy_node()
    rclpy.try_shutdown()


def test_goal_sent_before_the_planner_has_any_state_arrives(tmp_path, client):
    """The planner alone gets the goal; bridge and controller start after it: it arrives."""
    stack = Stack(tmp_path, planner={'state_wait_timeout': STATE_WAIT}, names=())
    try:
        stack.start('planner')
        assert client.spin_until(lambda: client.pose_pub.get_subscription_count() > 0
                                 and client.planner_status is not None, 60.0), stack.report()
        # The planner exists and has seen no state: it says so, and nothing publishes states.
        assert client.values(client.planner_status)['state'] == 'waiting_for_states'
        assert client.q is None
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.header.stamp = client.get_clock().now().to_msg()
        msg.pose = conversions.matrix_to_pose(GOAL)

        def publish_then_start_the_others():
            client.pose_pub.publish(msg)
            stack.start('sim_bridge')
            stack.start('controller')
        outcome = client.run_goal(publish_then_start_the_others, T_goal=GOAL,
                                  stamp=msg.header.stamp, timeout=120.0)
        assert outcome.arrived, f'{outcome}\n{stack.report()}'
        assert np.linalg.norm(fk(ARM, client.q)[:3, 3] - GOAL[:3, 3]) < 0.005
        log = stack.nodes['planner'].tail(200)
        assert 'waiting up to' in log, log       # it waited for the states, not refused
    finally:
        stack.stop_all()


@pytest.mark.skipif(not installed(), reason='needs the built package (./run.sh test)')
def test_goal_command_right_after_the_launcher_starts_arrives(tmp_path):
    """./run.sh launch, then at once ./run.sh goal (the Mover6 report's linear example)."""
    env = dict(os.environ)
    launcher = subprocess.Popen([os.path.join(ROOT, 'run.sh'), 'launch', '--log-dir',
                                 str(tmp_path / 'logs')], cwd=ROOT, env=env,
                                stdout=subprocess.DEVNULL,
                                stderr=open(tmp_path / 'launch.err', 'w'),
                                start_new_session=True)
    try:
        # Right after the launcher printed that it started the nodes (no wait for any state).
        assert wait_until(lambda: len(re.findall(
            r'started \w+ \(pid', (tmp_path / 'launch.err').read_text())) >= 3, 120.0), \
            (tmp_path / 'launch.err').read_text()
        proc = subprocess.run([os.path.join(ROOT, 'run.sh'), 'goal', '0.445', '0', '0.4425',
                               '0', '0', '0', '--timeout', '60'], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=300)
        out = proc.stdout + proc.stderr
        logs = '\n'.join(f'--- {p.name}\n{p.read_text()[-3000:]}'
                         for p in sorted((tmp_path / 'logs').glob('*')))
        assert proc.returncode == 0, f'{out}\n{logs}'
        assert 'RESULT arrived' in out, out
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGINT)
            try:
                launcher.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(launcher.pid, signal.SIGKILL)
                launcher.wait(10)
