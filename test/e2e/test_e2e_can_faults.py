"""
CAN faults in the middle of a goal, and the driver's end on a signal, on the can-sim stack.

The stack is ``mover6_control.stack``'s plan for ``--hardware can-sim`` (what ``./run.sh launch
--hardware can-sim`` starts): ``can_sim`` on a pty, the driver on it (enabled at start) and the
controller, each with the plan's parameters. The goals are joint goals on /joint_demands, so the
planner (and the helpers that only publish: state publisher, markers) is left out.

Each fault is injected through can_sim's control channel while the arm moves (a third of the way
into a goal): a module's error flag (position lag on joint 2), a silent module (joint 3), the
link lost (the adapter unplugged). For each:

- the arm holds: the simulated arm's true joint positions stop changing, and the time from the
  fault to the last change of more than an encoder tick is the *time to hold*;
- without a set-point jump: the set-points the modules took from the fault until recovery
  (can_sim's ``frames``) change by no more than one driver cycle at the joint's speed limit in
  one step; after the hold no module's set-point moves at all until recovery;
- the goal ends with the reason: the controller aborts it (not arrived) and the driver's bus
  status says why it holds;
- recovery works: reset and enable (replug first for the link) are confirmed, the arm stays where
  it held, and a new goal arrives.

The figures (largest set-point step after the fault [ticks and rad], time to hold [ms]) are
printed on a line starting ``mid-goal fault``: ``./run.sh test test/e2e/test_e2e_can_faults.py
-rA -s`` shows them.

Then the driver ends on SIGINT and on SIGTERM while enabled: every module gets a disable and
none is left enabled; the driver is started again from the same plan after each.
"""

import os
import signal
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from driver_client import add_driver_services, bus, call
from mover6_control.hardware.scaling import load_joints
from mover6_control.kinematics.arm import mover6
from mover6_control.parameters import DRIVER
from mover6_control.stack import parameter_text, plan
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import pytest
import rclpy
from ros_testing import CanSimProcess, NodeProcess, wait_until

pytestmark = pytest.mark.e2e

_, JOINTS = load_joints()
TICKS_PER_RAD = np.abs([j.ticks_per_rad for j in JOINTS])
# The joint limits the plan gives the driver and the controller on can-sim.
LIMIT_SET = {s.name: s for s in plan({'hardware': 'can_sim'})}['driver'].parameters['limit_set']
ARM = mover6(LIMIT_SET)
CYCLE = DRIVER['cycle'].default                      # [s] the driver's set-point cycle
# The most one cycle's set-point step may be [ticks]: the joint's speed limit over a cycle,
# plus the tick the wire rounds to.
STEP_BOUND = np.asarray(ARM.velocity_limits) * CYCLE * TICKS_PER_RAD + 1.0
AWAY = np.array([0.8, 0.35, 0.3, 0.5, -0.5, 0.6])   # [rad] the goal; home is zeros
HOME = np.zeros(6)
NODES = ('driver', 'controller')                    # with can_sim: what the goals go through


@pytest.fixture(scope='module')
def rig(tmp_path_factory):
    """Start can_sim, the driver and the controller as the can-sim stack's plan says."""
    logs = tmp_path_factory.mktemp('e2e_can_faults')
    link = logs / 'mover6-can'
    starts = {s.name: s for s in plan({'hardware': 'can_sim', 'can_channel': str(link)})}
    assert starts['can_sim'].parameters['link'] == str(link)
    rig = Rig(logs, starts)
    with CanSimProcess(logs, link) as sim:
        rig.sim = sim
        try:
            for name in NODES:
                rig.start(name)
            yield rig
        finally:
            for node in rig.nodes.values():
                node.interrupt()
            for node in rig.nodes.values():
                node.stop()


class Rig:
    """The processes of the plan: can_sim and the nodes, each started with the plan's params."""

    def __init__(self, logs, starts):
        self.logs, self.starts, self.nodes, self.sim = logs, starts, {}, None

    def start(self, name):
        """Start (again) node ``name`` with its parameter file and the plan's parameters."""
        params = {k: parameter_text(v) for k, v in self.starts[name].parameters.items()}
        self.nodes[name] = NodeProcess(name, self.logs, params)
        return self.nodes[name]

    def report(self):
        """Return the tail of every process's output."""
        return '\n'.join(f'--- {n.name} (alive={n.alive()}) ---\n{n.tail()}'
                         for n in [self.sim, *self.nodes.values()])


@pytest.fixture(scope='module')
def client(rig):
    """Return a goal client that keeps the driver's /diagnostics and calls its services."""
    rclpy.init()
    node = GoalClient(name='e2e_can_faults_client')
    node.diagnostics = {}

    def on_diagnostics(msg):
        for status in msg.status:
            node.diagnostics[status.name] = {kv.key: kv.value for kv in status.values}
    node.create_subscription(DiagnosticArray, 'diagnostics', on_diagnostics, 100)
    add_driver_services(node)
    try:
        problem = node.wait_ready(timeout=90.0, need_planner=False)
        assert problem is None, f'{problem}\n{rig.report()}'
        assert node.spin_until(lambda: bus(node).get('state') == 'enabled', 60.0), \
            f'{node.diagnostics}\n{rig.report()}'
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def true_q(sim):
    """Return the simulated arm's joint positions [rad]."""
    return np.array(sim.control('status')['q'])


def still_for(sim, seconds):
    """Return True once the true arm moved less than a tick over ``seconds`` of its own time."""
    start = sim.control('status')
    t0, q0 = start['time'], np.array(start['q'])
    moved = False

    def done():
        nonlocal moved
        status = sim.control('status')
        moved = moved or bool(np.any(np.abs(np.array(status['q']) - q0) * TICKS_PER_RAD > 1.0))
        return moved or status['time'] >= t0 + seconds
    assert wait_until(done, 30.0, period=0.01)
    return not moved


class MidGoalFault:
    """
    A thread that injects ``command`` once the arm is a third of the way to ``goal``.

    Then it samples the true joint positions until they have not changed for ``STILL`` [s]:
    ``t_fault`` (monotonic [s], the clock can_sim stamps frames with), ``samples`` [(t, q)],
    ``before`` the frames the modules took during the goal up to the fault.
    """

    STILL = 0.5

    def __init__(self, sim, start, goal, command):
        self.sim, self.start, self.goal, self.command = sim, start, goal, command
        self.t_fault = None
        self.answer = None
        self.samples = []
        self.before = None
        self.error = None
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        try:
            far = np.abs(self.goal - self.start)
            j = int(np.argmax(far))

            def a_third():
                q = true_q(self.sim)
                return abs(q[j] - self.start[j]) >= far[j] / 3
            if not wait_until(a_third, 60.0, period=0.005):
                self.error = 'the arm never got a third of the way'
                return
            self.before = self.sim.control('frames')['modules']
            self.t_fault = time.monotonic()
            self.answer = self.sim.control(self.command)
            still_since = time.monotonic()
            last = true_q(self.sim)
            self.samples.append((self.t_fault, last))
            while time.monotonic() - still_since < self.STILL:
                now, q = time.monotonic(), true_q(self.sim)
                self.samples.append((now, q))
                if np.any(np.abs(q - last) * TICKS_PER_RAD > 1.0):
                    last, still_since = q, now
                if now - self.t_fault > 30.0:
                    self.error = 'the arm did not come to rest within 30 s'
                    return
        except Exception as err:  # noqa: B902 - reported by the test
            self.error = f'{type(err).__name__}: {err}'

    def time_to_hold(self):
        """Return [s] from the fault to the last sample more than a tick from where it held."""
        q_end = self.samples[-1][1]
        moving = [t for t, q in self.samples if np.any(np.abs(q - q_end) * TICKS_PER_RAD > 1.0)]
        return (max(moving) if moving else self.t_fault) - self.t_fault


def setpoint_steps(modules, t_from=None):
    """Return each module's set-points [(t, ticks)] taken at or after ``t_from``, and the steps."""
    series = [[(t, ticks) for t, kind, ticks in m['frames'] if kind == 'setpoint'
               and (t_from is None or t >= t_from)] for m in modules]
    steps = np.array([max((abs(b[1] - a[1]) for a, b in zip(s, s[1:])), default=0)
                      for s in series], dtype=float)
    return series, steps


FAULTS = {
    # name: (command, the joint whose module fails or None, recovery before reset and enable)
    'error_flag': ('flags 2 0x10', 2, None),
    'silent_module': ('silent 3 on', 3, 'silent 3 off'),
    'link_lost': ('unplug', None, 'replug'),
}


@pytest.mark.parametrize('fault', list(FAULTS))
def test_a_fault_in_the_middle_of_a_goal_holds_and_recovers(rig, client, fault):
    sim = rig.sim
    command, joint, undo = FAULTS[fault]
    assert still_for(sim, 0.3), 'the arm moves before the goal'
    start = true_q(sim)
    goal = AWAY if np.abs(start - AWAY).max() > np.abs(start - HOME).max() else HOME
    sim.control('frames')                                   # from the goal on
    injector = MidGoalFault(sim, start, goal, command)
    outcome = client.send_joints([goal], timeout=60.0)
    injector.thread.join(60.0)
    assert injector.error is None and injector.answer == {'ok': True}, \
        f'{injector.error} {injector.answer}\n{rig.report()}'
    # The goal ends with the reason: the controller aborts it, the driver says why it holds.
    assert not outcome.arrived, f'{outcome}\n{rig.report()}'
    assert client.spin_until(lambda: bus(client).get('hold', '') != '', 10.0), bus(client)
    hold_reason = bus(client)['hold']
    if joint is not None:
        assert f'joint{joint}' in hold_reason or client.diagnostics.get(
            f'driver: joint{joint}', {}).get('state') in ('fault', 'error'), client.diagnostics
    t_ended = time.monotonic() - injector.t_fault
    held_at = true_q(sim)
    held = sim.control('status')
    t_hold = injector.time_to_hold()
    # The arm holds where the driver held it: every module at its last set-point (to a tick).
    off = [abs(p - m['setpoint']) for p, m in zip(held['positions'], held['modules'])]
    assert max(off) <= 1, (off, held['modules'])
    # Recovery: the fault undone, then reset and enable, each confirmed.
    if undo is not None:
        assert sim.control(undo)['ok']
    for kind in ('reset', 'enable'):
        answer = None

        def confirmed():
            nonlocal answer
            answer = call(client, kind)
            return answer.success
        # After a replug the driver reads every position again first: reset is refused
        # (with its reason) until it has.
        assert client.spin_until(confirmed, 30.0), f'{kind}: {answer.message}\n{rig.report()}'
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled'
                             and bus(client).get('hold') == '', 10.0), bus(client)
    after = sim.control('frames')['modules']
    # The arm stayed where it held through the recovery, and stays there after the enable.
    assert np.all(np.abs(true_q(sim) - held_at) * TICKS_PER_RAD <= 1.0), \
        (true_q(sim) - held_at) * TICKS_PER_RAD
    assert still_for(sim, 0.5), 'the arm moved after the enable with no goal'
    # No set-point jump from the fault to the end of the recovery.
    _, before_steps = setpoint_steps(injector.before)
    series, steps = setpoint_steps(after, injector.t_fault)
    # The driver holds at the second cycle after the fault: the next cycle's set-points are
    # out before their replies (the flag, or a reply missing) are read, the one after holds.
    t_frozen = injector.t_fault + 2 * CYCLE
    changes = [t for s in series for a, (t, ticks) in zip(s, s[1:]) if ticks != a[1]
               and t <= enable_time(after)]
    t_last_change = max(changes, default=injector.t_fault) - injector.t_fault
    # A module that stopped itself (its error flag) is not enabled: its set-point follows its
    # measured position, which is where it held (checked above); every other one is frozen.
    moved_after_hold = [j + 1 for j, s in enumerate(series) if held['modules'][j]['enabled']
                        and len({ticks for t, ticks in s if t_frozen <= t <= enable_time(after)})
                        > 1]
    worst = int(np.argmax(steps / TICKS_PER_RAD))
    print(f'mid-goal fault {fault} ({command}): largest set-point step after the fault '
          f'{steps[worst]:.0f} ticks = {steps[worst] / TICKS_PER_RAD[worst]:.5f} rad '
          f'(joint{worst + 1}; per joint {steps.astype(int).tolist()} ticks, during the goal '
          f'{before_steps.astype(int).tolist()}); last set-point change '
          f'{1000 * t_last_change:.0f} ms after the fault; arm still (within a tick) '
          f'{1000 * t_hold:.0f} ms after it; goal ended {1000 * t_ended:.0f} ms after it: '
          f'{outcome.text}; driver: {hold_reason}')
    assert np.all(steps <= STEP_BOUND), (steps.tolist(), STEP_BOUND.tolist())
    moved = [[(round(t - injector.t_fault, 3), k, x) for t, k, x in after[j - 1]['frames']
              if t <= enable_time(after)] for j in moved_after_hold]
    assert moved_after_hold == [], f'set-points moved after the hold: {moved_after_hold}: {moved}'
    # A new goal arrives.
    outcome = client.send_joints([HOME if goal is AWAY else AWAY], timeout=60.0)
    assert outcome.arrived, f'{outcome}\n{rig.report()}'


def enable_time(modules):
    """Return the time of the last enable any module took (the end of the recovery)."""
    times = [t for m in modules for t, kind, _ in m['frames'] if kind == 'enable']
    assert times, 'no enable reached the modules'
    return max(times)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM],
                         ids=['SIGINT', 'SIGTERM'])
def test_the_driver_ending_on_a_signal_disables_every_module(rig, client, signum):
    sim = rig.sim
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled', 30.0), bus(client)
    assert all(m['enabled'] for m in sim.control('status')['modules'])
    sim.control('frames')
    driver = rig.nodes['driver']
    os.kill(driver.pid, signum)
    assert wait_until(lambda: not driver.alive(), 30.0), rig.report()
    assert driver.stop() == 0, rig.report()
    status = sim.control('status')
    frames = sim.control('frames')['modules']
    disabled = [j + 1 for j, m in enumerate(frames)
                if any(kind == 'disable' for _, kind, _ in m['frames'])]
    print(f'driver ended on {signal.Signals(signum).name}: disable frames for joints '
          f'{disabled}; enabled after: {[m["enabled"] for m in status["modules"]]}')
    assert disabled == [1, 2, 3, 4, 5, 6], frames
    assert not any(m['enabled'] for m in status['modules']), status['modules']
    # Started again from the plan (enable_on_start on can-sim): enabled again.
    client.diagnostics.clear()
    rig.start('driver')
    assert client.spin_until(lambda: bus(client).get('state') == 'enabled', 90.0), \
        rig.report()
