"""
End to end on the CAN-level Mover6: planner -> controller -> /JointJog -> driver -> pty -> modules.

Processes over DDS as a user runs them: ``can_sim`` (six simulated motor modules on the MuJoCo
arm, speaking the CPR USB2CAN framing on a pty), the driver on that pty (``cpr_usb2can``, exactly
as on /dev/ttyUSB0), the controller and the planner, all with the vendor's joint limits. A goal
arrives when the controller says so and, once the controller has settled, both the simulated
arm's true encoder counts and /joint_states (the driver's readings of them) are within one
encoder tick of the goal for every joint (each joint's error in ticks is printed); faults are
injected through can_sim's control socket and recovered through the driver's services.
"""

import os
import signal
import subprocess
import time

from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticArray
from driver_client import add_driver_services, bus, call
from geometry_msgs.msg import PoseStamped
from mover6_control.hardware.scaling import load_joints
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages.conversions import matrix_to_pose, status_values
from mover6_control.parameters import DRIVER
from mover6_control.resources import executable_command
from mover6_control.tools.goal_cli import GoalClient
from mover6_control.tools.goal_convention import poses_from_numbers
import numpy as np
import pytest
from ros_testing import CanSimProcess, ready_client, Stack

pytestmark = pytest.mark.e2e

_, JOINTS = load_joints()
ARM = mover6('hardware')
TICK = np.array([j.tick for j in JOINTS])
TICKS_PER_RAD = np.array([j.ticks_per_rad for j in JOINTS])
OFFSET = np.array([j.offset for j in JOINTS])
COMMAND_TIMEOUT, CYCLE = 0.2, 0.05                 # the driver's defaults (config/driver.yaml)
# The README's first goal: the Mover6 report's linear example, 10 cm along x from home.
# X Y Z A B C with A B C from the home orientation, as the README writes goals.
GOAL = poses_from_numbers([0.445, 0.0, 0.4425, 0.0, 0.0, 0.0], quat=False, arm=ARM)[-1]
HOME = poses_from_numbers([0.345, 0.0, 0.4425, 0.0, 0.0, 0.0], quat=False, arm=ARM)[-1]
# Half way back (a linear move onto HOME itself ends in its singularity and is refused).
MID = poses_from_numbers([0.395, 0.0, 0.4425, 0.0, 0.0, 0.0], quat=False, arm=ARM)[-1]
# The stack as scripts/launch.sh --hardware can-sim --limit-set hardware starts it (the
# stack definition's parameters: the driver's six silent cycles, the modules' 0.5 s watchdog,
# can_sim's default, the controller's state_timeout with the driver). Nothing here is given more
# than a real arm gets.
OPTIONS = {'hardware': 'can_sim', 'limit_set': 'hardware'}


@pytest.fixture(scope='module')
def rig(tmp_path_factory):
    """Start can_sim, then the driver on its pty (enabled at start), controller and planner."""
    logs = tmp_path_factory.mktemp('e2e_can_logs')
    with CanSimProcess(logs, logs / 'mover6-can') as sim:
        with Stack(logs, options=dict(OPTIONS, can_channel=sim.link),
                   names=('driver', 'controller', 'planner')) as stack:
            stack.nodes['can_sim'] = sim
            yield sim, stack


@pytest.fixture(scope='module')
def client(rig):
    """Return a goal client that also keeps /JointJog times and the driver's /diagnostics."""
    _, stack = rig

    def make():
        node = GoalClient(name='e2e_can_client')
        node.jog_stamps = []
        node.diagnostics = {}
        node.jogs = []

        def on_jog(msg):
            node.jog_stamps.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
            node.jogs.append((time.monotonic(), list(msg.joint_names), list(msg.velocities)))
        node.create_subscription(JointJog, 'JointJog', on_jog, 100)

        def on_diagnostics(msg):
            for status in msg.status:
                node.diagnostics[status.name] = {kv.key: kv.value for kv in status.values}
        node.create_subscription(DiagnosticArray, 'diagnostics', on_diagnostics, 100)
        add_driver_services(node)
        return node
    with ready_client(stack, make, timeout=60.0) as node:
        assert node.spin_until(lambda: node.count_publishers('joint_demands') >= 2
                               and node.count_subscribers('joint_demands') >= 2, 30.0), \
            'planner or controller not on /joint_demands\n' + stack.report()
        yield node


def recover(client, stack):
    """~/reset then ~/enable: both confirmed, and the bus reports the arm enabled."""
    for kind in ('reset', 'enable'):
        answer = call(client, kind)
        assert answer.success, f'{kind}: {answer.message}\n{stack.report()}'
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled', 10.0), \
        f'{bus(client)}\n{stack.report()}'


def true_q(sim):
    """Return the simulated arm's joint positions [rad]."""
    return np.array(sim.control('status')['q'])


def true_state(sim):
    """Return the simulated arm's joint positions [rad] and encoder counts [ticks, no offset]."""
    status = sim.control('status')
    return np.array(status['q']), np.array(status['positions']) - OFFSET


def assert_arrived(client, sim, stack, T_goal, label):
    """
    Send a pose goal; it arrives and settles to one encoder tick of the goal on every joint.

    Once the controller is idle (settled) and the arm rests, the modules' true encoder counts
    and /joint_states are each within one tick of the goal, per joint; the errors in ticks are
    printed (``label`` names the run).
    """
    client.jogs.clear()
    outcome = client.send_pose(T_goal, timeout=60.0)
    t_arrived = time.monotonic()
    assert outcome.arrived, f'{outcome}\n{stack.report()}'
    assert client.spin_until(
        lambda: status_values(client.controller_status).get('state') == 'idle', 10.0)
    q_goal = client.last_demands[-1]
    # The arm rests: three readings, and the true positions between them.
    for _ in range(3):
        stamp = client.q
        assert client.spin_until(lambda: client.q is not stamp, 5.0)
    q_js, (q_true, ticks) = client.q.copy(), true_state(sim)
    true_error = ticks - q_goal * TICKS_PER_RAD              # [ticks]
    reading_error = (q_js - q_goal) / TICK                   # [ticks]
    message = client.controller_status.message
    print(f'{label}: final joint error [ticks] true '
          f'{" ".join(f"{e:+.3f}" for e in true_error)}; /joint_states '
          f'{" ".join(f"{e:+.3f}" for e in reading_error)}; controller: {message}')
    report = ('true - goal [ticks]', true_error.round(3).tolist(),
              '/joint_states - goal [ticks]', reading_error.round(3).tolist(),
              'controller', message,
              '/JointJog from 0.2 s before arrival on, the non-zero ones',
              [(round(t - t_arrived, 3), [round(x, 6) for x in v]) for t, _, v in client.jogs
               if t > t_arrived - 0.2 and any(v)])
    assert np.all(np.abs(true_error) <= 1.0), report
    assert np.all(np.abs(reading_error) <= 1.0), report
    assert np.all(np.abs(q_js - q_true) <= TICK), f'{(q_js - q_true) / TICK} ticks'


def assert_holds(client, sim, stack, state, check):
    """Wait for the driver to report ``state`` and ``check(diagnostics)``; the arm stays put."""
    assert client.spin_until(lambda: bus(client).get('state') == state
                             and check(client.diagnostics), 10.0), \
        f'{client.diagnostics}\n{stack.report()}'
    assert bus(client).get('hold'), bus(client)
    q0 = true_q(sim)
    sim_runs(client, sim, 0.5)
    assert np.all(np.abs(true_q(sim) - q0) <= TICK)


def sim_runs(client, sim, seconds):
    """Spin until the simulated arm's physics has run ``seconds`` [s] more (its own clock)."""
    start = sim.control('status')['time']
    assert client.spin_until(lambda: sim.control('status')['time'] >= start + seconds, 30.0)


def setpoints_still(sim, cycles):
    """Return whether no module's set-point changed for ``cycles`` driver cycles."""
    changed = max(m['setpoint_changed'] for m in sim.control('status')['modules'])
    return time.monotonic() - changed > cycles * CYCLE


def test_readme_goal_arrives_in_rad_per_s(rig, client):
    sim, stack = rig
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled', 10.0), \
        client.diagnostics
    assert_arrived(client, sim, stack, GOAL, 'rad_per_s')


def test_a_killed_controller_stops_the_arm(rig, client):
    """Kill the controller mid-move: set-points stop within command_timeout + one cycle."""
    sim, stack = rig
    client.jog_stamps.clear()
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    away = np.max(np.abs(true_q(sim))) > 0.1           # away from home: go back, else out
    msg.pose = matrix_to_pose(MID if away else GOAL)
    client.wait_matched(client.pose_pub)
    client.pose_pub.publish(msg)
    moving = [true_q(sim)]
    assert client.spin_until(lambda: np.any(np.abs(true_q(sim) - moving[0]) > 0.02), 30.0), \
        stack.report()
    os.kill(stack.nodes['controller'].pid, signal.SIGKILL)
    # The set-points stop: none changed for four cycles (the bound is checked below).
    assert client.spin_until(lambda: setpoints_still(sim, 4), 10.0), stack.report()
    last_jog = max(client.jog_stamps)                       # system clock [s]
    status = sim.control('status')
    changed = max(m['setpoint_changed'] for m in status['modules'])   # monotonic [s]
    changed_wall = changed + (time.time() - time.monotonic())
    assert changed_wall - last_jog <= COMMAND_TIMEOUT + CYCLE, (changed_wall - last_jog)
    q0 = true_q(sim)
    sim_runs(client, sim, 0.5)
    assert np.all(np.abs(true_q(sim) - q0) <= TICK), (true_q(sim) - q0) / TICK
    stack.start('controller')
    assert client.wait_ready(timeout=60.0) is None, stack.report()


def test_a_silent_module_holds_and_recovers(rig, client):
    sim, stack = rig
    assert sim.control('silent 3 on')['ok']
    try:
        assert_holds(client, sim, stack, 'fault',
                     lambda d: d.get('driver: joint3', {}).get('state') == 'fault')
    finally:
        assert sim.control('silent 3 off')['ok']
    recover(client, stack)


def test_an_injected_position_lag_holds_and_recovers(rig, client):
    sim, stack = rig
    assert sim.control('flags 2 0x10')['ok']
    assert_holds(client, sim, stack, 'error', lambda d: 'position_lag' in d.get(
        'driver: joint2', {}).get('flag_names', ''))
    recover(client, stack)


def test_corrupted_bytes_hold_and_recover(rig, client):
    sim, stack = rig
    dropped = int(bus(client).get('frames_dropped', '0'))
    silent_cycles = DRIVER['silent_cycles'].default        # shipped: 6
    assert sim.control(f'corrupt {6 * (silent_cycles + 5)}')['ok']    # every reply, 11 cycles
    assert_holds(client, sim, stack, 'fault',
                 lambda d: int(d.get('driver: bus', {}).get('frames_dropped', '0')) > dropped)
    recover(client, stack)


def test_readme_goal_arrives_in_fraction_of_max(rig, client):
    """Restart driver and controller in the vendor's units; the same goal arrives."""
    sim, stack = rig
    stack.choose(jog_units='fraction_of_max')     # --jog-units fraction-of-max
    for name in ('driver', 'controller'):       # both stop at once, then start again
        stack.nodes[name].interrupt()
    stack.start('driver')
    stack.start('controller')
    assert client.spin_until(lambda: status_values(client.controller_status).get(
        'jog_units') == 'fraction_of_max', 60.0), stack.report()
    assert client.wait_ready(timeout=60.0) is None, stack.report()
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled', 30.0)
    assert_arrived(client, sim, stack, GOAL, 'fraction_of_max')


@pytest.mark.parametrize('params, reason', [
    (['-p', 'frame_log:=/nonexistent-folder/frames.log'], 'cannot be written'),
    (['-p', 'listen_only:=true', '-p', 'enable_on_start:=true'], 'listen_only sends nothing'),
])
def test_the_driver_refuses_to_start_with_a_bad_observability_setting(tmp_path, params, reason):
    """Exit code 1 with the reason, before the bus is opened (the channel does not exist)."""
    cmd = executable_command('driver') + ['--ros-args', '-p', 'can_interface:=cpr_usb2can',
                                          '-p', f'can_channel:={tmp_path}/no-such-port'] + params
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    assert reason in out and 'no-such-port' not in out, out
