"""
Two arms in one graph: two namespaced stacks (scripts/launch.sh --namespace) moving at once.

Each stack is the whole launcher (bridge, controller, planner, state publisher, markers) under
its namespace; the goal CLI (``--namespace``) sends each its own goal at the same time. Each arm
must arrive at its own goal (judged from its own /NS/joint_states by forward kinematics), the
root namespace must carry no arm topic (neither stack heard the other's commands), and /tf must
carry both arms' frames with their prefixes. A malformed namespace is refused at start by the
launcher and by the goal CLI, with the ROS naming rule it breaks.
"""

import os
import re
import signal
import subprocess
import sys

# conftest.py keeps discovery on loopback and gives this test run its own ROS_DOMAIN_ID.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from mover6_control.kinematics.arm import mover6  # noqa: E402
from mover6_control.kinematics.forward import fk  # noqa: E402
from mover6_control.nodes.messages import conversions  # noqa: E402
from mover6_control.resources import CONFIG_DIR  # noqa: E402
from mover6_control.tools.goal_convention import (  # noqa: E402
    EXIT_ARRIVED, EXIT_REFUSED, pose_from_goal)
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import rclpy  # noqa: E402
from ros_testing import wait_until  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

pytestmark = pytest.mark.e2e

SCRIPT = os.path.join(os.path.dirname(CONFIG_DIR), 'scripts', 'launch.sh')
ARM = mover6()
# Each arm its own goal (X Y Z A B C from home, as the goal CLI reads them).
GOALS = {'/arm1': (0.30, 0.05, 0.36, 0.0, 0.0, 0.0), '/arm2': (0.445, 0.0, 0.4425, 0.0, 0.0, 0.0)}
LIMIT = 60.0      # [s] generous limit of every wait


def goal_command(namespace, numbers):
    """Return the goal CLI's command line for ``numbers`` in ``namespace``."""
    return [sys.executable, '-m', 'mover6_control.tools.goal_cli', '--namespace', namespace,
            *[str(v) for v in numbers], '--timeout', '90']


@pytest.fixture(scope='module')
def stacks(tmp_path_factory):
    """Start launch.sh twice, under /arm1 and /arm2; stop both by pid afterwards."""
    logs = tmp_path_factory.mktemp('two_arms')
    procs = {}
    for ns in GOALS:
        log_dir = logs / ns.strip('/')
        procs[ns] = (subprocess.Popen(
            ['bash', SCRIPT, '--namespace', ns, '--log-dir', str(log_dir)],
            stdout=subprocess.DEVNULL, stderr=open(logs / f'{ns.strip("/")}.err', 'w'),
            start_new_session=True), log_dir)
    yield procs
    for proc, _ in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    for proc, _ in procs.values():
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(5)


def test_two_namespaced_arms_move_at_once_each_to_its_own_goal(stacks):
    """Both goals sent together arrive; each arm holds its own goal; nothing at the root."""
    rclpy.init()
    node = rclpy.create_node('two_arms_watcher')
    states = {ns: [] for ns in GOALS}
    frames = set()
    for ns in GOALS:
        node.create_subscription(JointState, f'{ns}/joint_states', states[ns].append, 10)
    node.create_subscription(TFMessage, '/tf', lambda m: frames.update(
        t.child_frame_id for t in m.transforms), 100)
    try:
        def spin(period):
            rclpy.spin_once(node, timeout_sec=period)
        assert wait_until(lambda: all(states.values()), LIMIT, spin), \
            {ns: p.poll() for ns, (p, _) in stacks.items()}
        clis = {ns: subprocess.Popen(goal_command(ns, GOALS[ns]), stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
                for ns in GOALS}
        assert wait_until(lambda: all(p.poll() is not None for p in clis.values()), 120.0,
                          spin)
        outputs = {ns: p.stdout.read() for ns, p in clis.items()}
        for ns, proc in clis.items():
            assert proc.returncode == EXIT_ARRIVED, f'{ns}:\n{outputs[ns]}'
        # The arms' own measured states, a moment after the end: each at its own goal.
        for ns in GOALS:
            states[ns].clear()
        assert wait_until(lambda: all(states.values()), LIMIT, spin)
        for ns, goal in GOALS.items():
            q = conversions.joint_state_from_msg(states[ns][-1], ARM.joint_names)[0]
            error = np.linalg.norm(fk(ARM, q)[:3, 3] - pose_from_goal(ARM, *goal)[:3, 3])
            print(f'{ns}: arrived, final tool position error {error * 1e3:.2f} mm; '
                  + re.search(r'RESULT.*', outputs[ns]).group(0))
            assert error < 0.005, f'{ns} is {error * 1e3:.1f} mm from its goal'
        # Neither stack talked in the other's namespace nor at the root.
        topics = dict(node.get_topic_names_and_types())
        for name in ('/joint_states', '/JointJog', '/joint_demands', '/pose_goal',
                     '/controller/status', '/planner/status'):
            assert name not in topics, f'{name} exists at the root: {sorted(topics)}'
        for ns in GOALS:
            assert f'{ns}/JointJog' in topics and f'{ns}/robot_description' in topics
        assert wait_until(lambda: {'arm1/link6', 'arm2/link6'} <= frames, LIMIT, spin), frames
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


@pytest.mark.parametrize('namespace, rule', [
    ('1arm', 'token that starts with a number'), ('arm-1', "other than alphanumerics, '_'"),
    ('a//b', "repeated '/'"), ('arm1/', "must not end with a '/'")])
def test_malformed_namespace_refused_at_start(tmp_path, namespace, rule):
    """launch.sh and the goal CLI refuse it with the rule, before any node starts."""
    done = subprocess.run(['bash', SCRIPT, '--namespace', namespace, '--log-dir',
                           str(tmp_path / 'logs')], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and rule in done.stderr, done.stderr
    assert 'started' not in done.stderr
    done = subprocess.run(goal_command(namespace, GOALS['/arm1']), capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == EXIT_REFUSED and rule in done.stderr, done.stderr
