"""
The local DDS configuration: what the test run used, what the nodes bind, who refuses.

The package's local configuration (UDP on 127.0.0.1, unicast discovery to 127.0.0.1, no shared
memory) is the launchers' default on every machine. ``./run.sh test`` runs the suite inside a
private network namespace when the machine allows one (``MOVER6_TEST_NETWORK=netns``), then this
module and the churn test again on the host network (marker ``host_network``,
``MOVER6_TEST_NETWORK=host``), where every node's sockets must be on loopback too;
``test_the_run_used_what_run_sh_said`` fails when the run fell back silently. The tests that
start nodes in a configuration that could leave loopback (Fast DDS's defaults without the
profile) run only inside a private network namespace (nothing sent there can leave the
machine).
"""

import os
import socket
import subprocess
import sys

from mover6_control.nodes.runtime import local_dds
from mover6_control.resources import CONFIG_DIR
from mover6_control.resources import executable_command
import pytest
import rclpy
from ros_testing import Stack, wait_until

pytestmark = [pytest.mark.e2e, pytest.mark.host_network]

ROOT = os.path.dirname(CONFIG_DIR)


def in_private_netns():
    """Return True when this network namespace has no interface but loopback."""
    return [name for _, name in socket.if_nameindex()] == ['lo']


def machine_allows_netns():
    """Return True when a private network namespace can be made here (as run.sh makes one)."""
    commands = (['unshare', '-n', 'true'], ['unshare', '-rn', 'true'])
    for cmd in commands if os.getuid() == 0 else commands[1:]:
        try:
            if subprocess.run(cmd, capture_output=True, timeout=30).returncode == 0:
                return True
        except (OSError, subprocess.TimeoutExpired):
            pass
    return False


netns_only = pytest.mark.skipif(not in_private_netns(),
                                reason='starts DDS without the profile (multicast on every '
                                'interface): only inside a private network namespace '
                                '(./run.sh test makes one)')
local_only = pytest.mark.skipif(not local_dds.requested(),
                                reason='needs the local DDS configuration (./run.sh test sets '
                                'it; a DDS setup of your own was chosen)')


def local_env(**changes):
    """Return this environment with ``changes`` (a value None removes the variable)."""
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    for key, value in changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    return env


@pytest.mark.skipif('MOVER6_TEST_NETWORK' not in os.environ,
                    reason='not started by ./run.sh test (it says which network it used)')
def test_the_run_used_what_run_sh_said():
    """A private namespace and the local configuration when the machine allows one, else none."""
    network = os.environ['MOVER6_TEST_NETWORK']
    assert network in ('netns', 'host'), network
    if network == 'host':
        if os.environ.get('MOVER6_NETNS') != '0':       # not asked for the host network
            assert not machine_allows_netns(), \
                'this machine allows a private network namespace, but the tests ran without one'
    else:
        assert in_private_netns(), f'interfaces: {socket.if_nameindex()}'
    assert local_dds.requested()
    local_dds.check_environment()          # SYSTEM_DEFAULT, the shipped profile, no override
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'


@pytest.fixture(scope='module')
def stack(tmp_path_factory):
    """Start the three nodes once for the tests of this module that need them running."""
    with Stack(tmp_path_factory.mktemp('local_dds_logs')) as running:
        yield running


@local_only
def test_nodes_bind_loopback_only_and_join_no_multicast_group(stack):
    """Every node's sockets are bound to 127.0.0.1; no multicast group is joined."""
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('dds_probe', context=context)
    try:
        wanted = {'sim_bridge', 'controller', 'planner'}
        up = wait_until(lambda: wanted <= set(node.get_node_names()), 60.0)
        assert up, f'{node.get_node_names()}\n{stack.report()}'
        pids = {name: proc.pid for name, proc in stack.nodes.items()}
        pids['this test'] = os.getpid()
        for name, pid in pids.items():
            sockets = local_dds.ip_sockets(pid)
            assert sockets, f'{name}: no socket'
            assert local_dds.not_loopback(sockets) == [], f'{name}: {sockets}'
        if in_private_netns():      # on a host, other programs' groups are listed too
            assert local_dds.multicast_groups() == [], open('/proc/net/igmp').read()
        assert all(proc.alive() for proc in stack.nodes.values()), stack.report()
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@local_only
def test_a_localhost_client_without_the_profile_sees_and_drives_the_nodes(stack):
    """The goal CLI as a user types it (only LOCALHOST, shared memory and UDP) moves the arm."""
    env = local_env(ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', MOVER6_DDS=None,
                    FASTRTPS_DEFAULT_PROFILES_FILE=None)
    done = subprocess.run(
        [sys.executable, '-m', 'mover6_control.tools.goal_cli', '0.30', '-0.08', '0.32', '0',
         '0', '0', '--timeout', '60'], env=env, capture_output=True, text=True,
        timeout=180, cwd=ROOT)
    out = done.stdout + done.stderr
    assert done.returncode == 0, f'{out}\n{stack.report()}'
    assert 'RESULT arrived' in out


def run_node_with(env, timeout=60):
    """Run sim_bridge with ``env``; return (exit code, output)."""
    cmd = executable_command('sim_bridge') + ['--ros-args', '--params-file',
                                              os.path.join(CONFIG_DIR, 'sim_bridge.yaml')]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT)
    return done.returncode, done.stdout + done.stderr


@netns_only
@pytest.mark.parametrize('changes, reason', [
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}, 'not SYSTEM_DEFAULT'),
    ({'FASTRTPS_DEFAULT_PROFILES_FILE': None}, 'FASTRTPS_DEFAULT_PROFILES_FILE is not set'),
    ({'FASTRTPS_DEFAULT_PROFILES_FILE': os.path.join(CONFIG_DIR, 'controller.yaml')},
     'is not the shipped profile'),
    ({'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT'}, 'overrides the profile'),
    ({'MOVER6_DDS': 'loopback'}, "the values are 'local'"),
])
def test_a_node_asked_for_the_local_profile_that_lacks_it_refuses_to_start(changes, reason):
    """Exit code 1 with the reason, before rclpy starts (so it sends nothing)."""
    env = local_env(**dict(local_dds.local_environment(), **changes))
    code, out = run_node_with(env)
    assert code == 1, out
    assert reason in out, out
    assert 'Not starting' in out or 'the values are' in out, out


@netns_only
def test_a_participant_that_fast_dds_set_up_otherwise_is_refused():
    """The socket check: Fast DDS's defaults (no profile loaded) bind beyond 127.0.0.1."""
    script = (
        'import rclpy\n'
        'from mover6_control.nodes.runtime import local_dds\n'
        'rclpy.init()\n'
        'try:\n'
        '    local_dds.make_checked_node(lambda: rclpy.create_node("never_made"))\n'
        'except local_dds.LocalDdsError as err:\n'
        '    print("REFUSED", err)\n'
        'else:\n'
        '    print("MADE")\n'
        'rclpy.try_shutdown()\n')
    # SYSTEM_DEFAULT without a profile: multicast discovery on every interface (here: only lo).
    env = local_env(MOVER6_DDS='local', ROS_AUTOMATIC_DISCOVERY_RANGE='SYSTEM_DEFAULT',
                    FASTRTPS_DEFAULT_PROFILES_FILE=None)
    done = subprocess.run([sys.executable, '-c', script], env=env, capture_output=True,
                          text=True, timeout=60, cwd=ROOT)
    out = done.stdout + done.stderr
    assert 'REFUSED' in out and 'not bound to 127.0.0.1' in out, out


def test_the_launchers_keep_a_users_dds_setup():
    """The local configuration only when the user set no DDS variable of their own."""
    assert local_dds.default_environment({'HOME': '/'}) == local_dds.local_environment()
    for name in local_dds.USER_DDS_ENV:
        if name != local_dds.MODE_ENV:
            assert local_dds.default_environment({name: 'x'}) == {}, name
    out = subprocess.run([sys.executable, '-m', 'mover6_control.nodes.runtime.local_dds', 'env'],
                         env=local_env(ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET'),
                         capture_output=True, text=True, timeout=30).stdout
    assert out == ''
    bare = {k: v for k, v in os.environ.items() if k not in local_dds.USER_DDS_ENV}
    for env in (bare, dict(bare, MOVER6_DDS='local')):
        # The local configuration, on this machine's network as in a namespace.
        module = 'mover6_control.nodes.runtime.local_dds'
        out = subprocess.run([sys.executable, '-m', module, 'env'],
                             env=env, capture_output=True, text=True, timeout=30).stdout
        assert "export MOVER6_DDS='local'" in out
        assert "export ROS_AUTOMATIC_DISCOVERY_RANGE='SYSTEM_DEFAULT'" in out
        assert f"export FASTRTPS_DEFAULT_PROFILES_FILE='{local_dds.PROFILE}'" in out
    # MOVER6_DDS=localhost: ROS's LOCALHOST discovery, as before.
    out = subprocess.run([sys.executable, '-m', 'mover6_control.nodes.runtime.local_dds', 'env'],
                         env=dict(bare, MOVER6_DDS='localhost'), capture_output=True, text=True,
                         timeout=30).stdout
    assert out == "export ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST'\n", out


def test_the_default_is_local_on_every_machine():
    """Without a DDS choice: the profile; MOVER6_DDS=localhost: LOCALHOST; a user's own: kept."""
    assert local_dds.default_environment({}) == local_dds.local_environment()
    assert local_dds.default_environment({'MOVER6_DDS': 'local'}) == \
        local_dds.local_environment()
    assert local_dds.default_environment({'MOVER6_DDS': 'localhost'}) == \
        {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    assert local_dds.default_environment({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}) == {}
    with pytest.raises(local_dds.LocalDdsError, match="the values are 'local'"):
        local_dds.default_environment({'MOVER6_DDS': 'shm'})
