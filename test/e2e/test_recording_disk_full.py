"""The recorder as a process on a file system that fills up: it stops with the reason, stays up."""

import os
import shutil
import signal
import subprocess

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.runtime.qos import STATUS_QOS
from mover6_control.resources import executable_command
import numpy as np
import pytest
import rclpy
from ros_testing import wait_until
from sensor_msgs.msg import JointState

pytestmark = pytest.mark.e2e

LIMIT = 30.0      # [s] generous limit of every wait
NAMES = [f'joint{i}' for i in range(1, 7)]


@pytest.fixture(scope='module', autouse=True)
def ros():
    """Start rclpy once for the module (conftest.py gives the run its own ROS_DOMAIN_ID)."""
    rclpy.init()
    yield
    rclpy.try_shutdown()


def mount_namespace_works(folder):
    """Return True when a private mount namespace with a tmpfs can be made here (root)."""
    if os.geteuid() != 0 or not shutil.which('unshare'):
        return False
    probe = subprocess.run(['unshare', '-m', 'mount', '-t', 'tmpfs', '-o', 'size=64k', 'tmpfs',
                            str(folder)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return probe.returncode == 0


def test_disk_full_stops_the_recording_with_the_reason(tmp_path):
    """
    A recorder on a 256 kB file system (a tmpfs in its own mount namespace) fills it.

    It stops recording with the reason on ~/status and stays up; the publisher goes on
    undisturbed, and a Ctrl-C still ends the recorder cleanly.
    """
    small = tmp_path / 'small'
    small.mkdir()
    if not mount_namespace_works(small):
        pytest.skip('no private mount namespace here (needs root and unshare -m)')
    log = open(tmp_path / 'recorder.log', 'w')
    cmd = (['unshare', '-m', 'sh', '-c',
            'mount -t tmpfs -o size=256k tmpfs "$0" && exec "$@"', str(small)]
           + executable_command('recorder')
           + ['--ros-args', '-p', f'path:={small}/bag', '-p', 'topics:=/joint_states'])
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    node = rclpy.create_node('disk_full_tester')
    statuses = []
    node.create_subscription(DiagnosticStatus, '/recorder/status', statuses.append, STATUS_QOS)
    pub = node.create_publisher(JointState, '/joint_states', 10)
    rng = np.random.default_rng(1)
    sent = [0]
    try:
        def spin(period):
            # 8 kB of noise a message (zstd cannot shrink it): a 1 MB chunk in ~130 messages.
            msg = conversions.make_joint_state(NAMES, [0.0] * 6)
            msg.effort = rng.random(1000).tolist()
            pub.publish(msg)
            sent[0] += 1
            rclpy.spin_once(node, timeout_sec=period)

        def stopped():
            return statuses and statuses[-1].level == DiagnosticStatus.ERROR
        assert wait_until(stopped, 60.0, spin, period=0.005), \
            (tmp_path / 'recorder.log').read_text()
        reason = statuses[-1].message
        assert 'recording stopped' in reason and 'No space left on device' in reason, reason
        assert proc.poll() is None, 'the recorder must stay up'
        assert wait_until(lambda: pub.get_subscription_count() == 0, LIMIT,
                          lambda period: rclpy.spin_once(node, timeout_sec=period))  # let go
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        node.destroy_node()
        log.close()
    assert 'No space left on device' in (tmp_path / 'recorder.log').read_text()
