"""
The first power-on: in every state the arm may be found in, no set-point away from where it is.

The real classes in one process on synthetic time: ``ArmDriver`` with its shipped defaults
(cycle, frame gap, silent cycles, max lag) on a python-can ``virtual`` bus, and the CAN-level
Mover6 (``CanArm``: the MuJoCo arm behind six simulated modules that keep the last set-point
while disabled and drive there on enable, the worst a firmware may do). Every set-point a module
receives is recorded with the module's position at that moment and whether the module was
enabled; each test asserts, cycle by cycle, the largest distance between a set-point an enabled
module received (or kept, when it was enabled) and its position: at most one cycle of the
commanded motion (zero when nothing is commanded) plus the tick a set-point is rounded to.
``FIGURE`` lines print each state's largest distance (``pytest -s``).
"""

from dataclasses import replace
import itertools

import can
from mover6_control.hardware import protocol as p
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import load_joints
import numpy as np
import pytest
from sim_bridge.can_arm import ModuleTiming
from sim_bridge.can_sim import build_arm, BusServer
from sim_bridge.simulator import SimConfig

# The set-point discipline without referencing's hold (the joint file may say a joint needs no
# referencing; test_can_driver.py tests the hold and the referencing).
JOINTS = tuple(replace(j, reference_required=False) for j in load_joints()[1])
TPR = np.array([abs(j.ticks_per_rad) for j in JOINTS])       # [ticks/rad]
CHANNELS = itertools.count()
CYCLE = 0.05
SUBSTEPS = 10
PHYSICS_DT = SimConfig().physics_dt             # [s]


class Rig:
    """The driver and the arm on one virtual bus; every set-point recorded on arrival."""

    def __init__(self, home_q=None, limit_set='hardware', answers_commands=True):
        channel = f'first_power_on_{next(CHANNELS)}'
        self.t = 0.0
        self.arm = build_arm(home_q=home_q, answers_commands=answers_commands)
        self.buses = [can.Bus(interface='virtual', channel=channel) for _ in range(2)]
        self.server = BusServer(self.arm, self.buses[0], clock=lambda: self.t)
        self.driver = ArmDriver(self.buses[1], JOINTS, limit_set=limit_set,
                                clock=lambda: self.t)
        self.received = []         # (cycle, joint, set-point, position, enabled) [wire ticks]
        self.cycle_index = 0
        self.enabled_at = []       # (joint, kept set-point, position) at each enable taken
        receive = self.arm.receive

        def recording_receive(can_id, data, now):
            joint, _ = p.joint_of_id(can_id)
            module = self.arm.modules[joint - 1]
            was_enabled = module.enabled
            self.arm.advance(now)
            position = int(self.arm.positions()[joint - 1])
            out = receive(can_id, data, now)
            command = p.decode_command(data) if len(data) in (2, 4, 8) else None
            if command is not None and command.kind == 'setpoint':
                self.received.append((self.cycle_index, joint, command.position, position,
                                      module.enabled))
            if command is not None and command.kind == 'enable' and module.enabled and \
                    not was_enabled:
                self.enabled_at.append((joint, module.last_setpoint, position))
            return out
        self.arm.receive = recording_receive

    def run(self, duration, velocity=None):
        """Run driver cycles for ``duration`` [s], commanding ``velocity`` (6,) each cycle."""
        report = None
        for _ in range(int(round(duration / CYCLE))):
            self.cycle_index += 1
            if velocity is not None:
                self.driver.set_velocity(velocity, self.t)
            report = self.driver.step(self.t)
            for _ in range(SUBSTEPS):
                self.t += CYCLE / SUBSTEPS
                self.driver.send_due(self.t)
                self.server.poll(0.0)
        return report

    def request(self, kind, joints=None, timeout=2.0):
        """Make a request and run until it is answered; return (ok, reason)."""
        req = self.driver.request(kind, joints, timeout)
        for _ in range(int(timeout / CYCLE) + 5):
            if req.ok is not None:
                break
            self.run(CYCLE)
        return req.wait(0.0)

    def enable(self):
        """Reset and enable; both must be confirmed."""
        for kind in ('reset', 'enable'):
            ok, reason = self.request(kind)
            assert ok, reason

    def largest_gap(self, since_cycle=0):
        """
        Return per joint the largest |set-point - position| met enabled [ticks].

        Cycle by cycle since ``since_cycle``, the set-points kept at an enable included.
        """
        gap = np.zeros(6)
        for cycle, joint, setpoint, position, enabled in self.received:
            if enabled and cycle >= since_cycle:
                gap[joint - 1] = max(gap[joint - 1], abs(setpoint - position))
        for joint, kept, position in self.enabled_at:
            if kept is not None:
                gap[joint - 1] = max(gap[joint - 1], abs(kept - position))
        return gap

    def close(self):
        """Shut both buses."""
        for bus in self.buses:
            bus.shutdown()


@pytest.fixture
def rigs():
    made = []

    def make(**kwargs):
        made.append(Rig(**kwargs))
        return made[-1]
    yield make
    for r in made:
        r.close()


def allowed(velocity=None, following=True):
    """
    Return per joint one cycle of ``velocity`` [rad/s] in ticks, plus the rounding tick.

    ``following``: plus how far a moving simulated module trails its reference: one physics step
    of the motion (its loop acts on the last step's position): a moving joint's position at the
    arrival of a set-point is one step behind it plus this.
    """
    v = np.zeros(6) if velocity is None else np.abs(np.asarray(velocity, dtype=float))
    lag = PHYSICS_DT if following else 0.0
    return v * (CYCLE + lag) * TPR + 1.0


def largest_step(rig, since_cycle=0):
    """
    Return per joint the largest change between two consecutive set-points [ticks].

    Of set-points an enabled module received in consecutive cycles: what the driver alone decides.
    """
    step, last = np.zeros(6), {}
    for cycle, joint, setpoint, _, enabled in rig.received:
        if enabled and cycle >= since_cycle and last.get(joint, (None, -2))[1] == cycle - 1:
            step[joint - 1] = max(step[joint - 1], abs(setpoint - last[joint][0]))
        last[joint] = (setpoint, cycle) if enabled else (None, -2)
    return step


def figure(state, gap):
    """Print the state's largest distance: ticks, and radians of the worst joint."""
    worst = int(np.argmax(gap / TPR))
    print(f'FIGURE {state}: largest set-point-to-position distance {gap.astype(int).tolist()} '
          f'ticks, worst joint{worst + 1} {gap[worst] / TPR[worst]:.6f} rad')


HOME = np.array([0.3, -0.2, 0.4, -0.5, 0.3, -0.6])           # [rad] where the arm powers up


@pytest.mark.parametrize('answers_commands', [True, False])
def test_power_up(rigs, answers_commands):
    """No set-point before the position is known; enable at the measured position."""
    r = rigs(home_q=HOME, answers_commands=answers_commands)
    r.run(0.3)
    early = [(j, sp, pos) for _, j, sp, pos, _ in r.received[:6]]
    if answers_commands:        # the positions come with the disable's answers
        assert all(sp == pos for _, sp, pos in early), early
    r.enable()
    r.run(1.0)
    gap = r.largest_gap()
    figure(f'power-up (modules answer commands: {answers_commands})', gap)
    assert np.all(gap <= allowed()), gap
    assert np.allclose(r.arm.sim.q, HOME, atol=2.0 / TPR)


def test_after_reset_with_the_arm_moved_while_disabled(rigs):
    """The modules kept their last set-points; the arm was moved by hand while disabled."""
    r = rigs(home_q=HOME)
    r.enable()
    r.run(0.5, [0.1] * 6)
    r.run(0.5)
    assert r.request('reset')[0]
    r.run(0.2)
    r.arm.sim.reset(r.arm.sim.q + np.array([0.05, -0.05, 0.05, 0.1, -0.1, 0.2]))  # by hand
    r.run(0.3)
    since = r.cycle_index
    r.enable()
    r.run(1.0)
    gap = r.largest_gap(since)
    figure('after reset, the arm moved by hand while disabled', gap)
    assert np.all(gap <= allowed()), gap


def test_after_a_lost_module(rigs):
    """J6's replies lost: enable refused and J6 never enabled; after it answers again, clean."""
    r = rigs(home_q=HOME)
    r.arm.set_silent(6, True)
    r.run(0.5)
    ok, reason = r.request('reset')
    assert not ok and 'joint6' in reason
    ok, reason = r.request('enable')
    assert not ok and 'joint6' in reason and 'all six' in reason
    r.run(1.0)
    assert not any(m.enabled for m in r.arm.modules)
    assert np.allclose(r.arm.sim.q, HOME, atol=2.0 / TPR)      # J6 did not drive anywhere
    r.arm.set_silent(6, False)
    r.run(0.3)
    r.enable()
    r.run(0.5, [0.05] * 6)
    r.arm.set_silent(6, True)                                 # lost while moving
    report = r.run(0.5, [0.05] * 6)
    assert report.hold and 'joint6' in report.hold
    r.arm.set_silent(6, False)
    r.enable()
    r.run(0.5)
    gap = r.largest_gap()
    figure('after a lost module', gap)
    assert np.all(gap <= allowed([0.05] * 6)), gap
    assert np.all(largest_step(r) <= allowed([0.05] * 6, following=False))


@pytest.mark.parametrize('q1,v1', [(np.radians(120.0), -0.01), (1.75, -0.02), (1.75, 0.02)])
def test_outside_the_limit_set(rigs, q1, v1):
    """J1 found outside within_90_deg: it moves only inward, at the commanded speed."""
    home = HOME.copy()
    home[0] = q1
    r = rigs(home_q=home, limit_set='within_90_deg')
    r.enable()
    r.run(0.2)
    since = r.cycle_index
    jog = [v1, 0, 0, 0, 0, 0]
    r.run(1.0, jog)
    gap = r.largest_gap(since)
    figure(f'J1 at {q1:.3f} rad outside within_90_deg, jog {v1} rad/s', gap)
    assert np.all(gap <= allowed(jog)), gap
    assert np.all(largest_step(r, since) <= allowed(jog, following=False))
    moved = r.arm.sim.q[0] - q1
    if v1 < 0:       # inward: at the commanded speed, never a jump to the limit
        assert -abs(v1) * 1.2 - 0.002 <= moved < 0
    else:            # outward: nothing
        assert abs(moved) <= 2.0 / TPR[0]


def test_after_set_zero(rigs):
    """Set zero with its value: every joint reads angle 0 there; enable goes nowhere."""
    r = rigs(home_q=HOME)
    r.run(0.3)
    ok, reason = r.request('set_zero')
    assert ok, reason
    report = r.run(0.1)
    assert all(abs(j.q) <= JOINTS[i].tick for i, j in enumerate(report.joints)), report.joints
    since = r.cycle_index
    r.enable()
    r.run(1.0)
    gap = r.largest_gap(since)
    figure('after set zero', gap)
    assert np.all(gap <= allowed()), gap
    assert np.allclose(r.arm.sim.q, HOME, atol=2.0 / TPR)


def test_set_zero_is_confirmed_only_by_a_reply_after_its_second_frame(rigs):
    """A reply on its way when the second frame went confirms nothing."""
    r = rigs(home_q=HOME)
    r.run(0.3)
    req = r.driver.request('set_zero')
    r.run(CYCLE)                    # both frames sent; the replies so far predate the second
    assert req.ok is None
    r.run(2 * CYCLE)
    assert req.ok, req.reason


def test_after_referencing(rigs):
    r = rigs(home_q=HOME)
    r.enable()
    for n in range(1, 5):            # each drives to its switch at the referencing speed
        ok, reason = r.request('reference', [n], timeout=10.0)
        assert ok, reason
    # While a module drives itself to its switch the driver's set-point is its last reading:
    # one cycle behind, never ahead of it.
    speed = ModuleTiming().reference_speed
    gap = r.largest_gap()
    figure('while referencing', gap)
    assert np.all(gap <= allowed([speed] * 4 + [0.0] * 2)), gap
    since = r.cycle_index
    r.run(0.5, [0.05] * 6)
    gap = r.largest_gap(since)
    figure('after referencing', gap)
    assert np.all(gap <= allowed([0.05] * 6)), gap
    assert np.all(largest_step(r, since) <= allowed([0.05] * 6, following=False))


def test_a_jog_live_at_enable_moves_nothing(rigs):
    """Motion after an enable starts only from a command that arrives after it."""
    r = rigs(home_q=HOME)
    assert r.request('reset')[0]
    jog = [0.2, 0.2, 0.2, 0.2, 0.2, 0.2]
    req = r.driver.request('enable')
    while req.ok is None:
        r.run(CYCLE, jog)              # a stream, live through the enable
    assert req.ok, req.reason
    since = r.cycle_index
    q = r.arm.sim.q.copy()
    r.run(0.15)                        # its last command is younger than command_timeout
    assert np.all(np.abs(r.arm.sim.q - q) <= 2.0 / TPR), (r.arm.sim.q - q) * TPR
    r.run(0.5, jog)                    # a command after the enable moves it
    assert np.all(r.arm.sim.q - q > 0.05)
    gap = r.largest_gap(since)
    figure('a jog live at enable', gap)
    assert np.all(gap <= allowed(jog)), gap
    assert np.all(largest_step(r, since) <= allowed(jog, following=False))
