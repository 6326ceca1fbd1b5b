"""
The controller behind the CAN driver settles every joint onto the encoder tick nearest its goal.

The real classes in one process on synthetic time: ``ControllerCore`` (``cycle_driver``, as the
CAN stack's launch sets it) at 100 Hz, ``ArmDriver`` at its 50 ms cycle on a python-can
``virtual`` bus, and the CAN-level Mover6 (``CanArm``, the MuJoCo arm behind six simulated
modules) answering on that bus. The driver's readings reach the core ``reading_delay`` late, the
core's commands reach the driver ``command_delay`` late, in the JointJog units the driver node
reads (``fraction_of_max``: ``value * max speed * speed_override``). After each goal the core
goes idle (settled) and the modules' encoder counts are within one tick of the goal on every
joint: 8.3e-6 rad for J1-J4, 6.1e-3 rad for J5 and J6.
"""

from dataclasses import replace
import itertools

import can
from core_testing import send_demand, send_states
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.hardware.driver import ArmDriver
from mover6_control.hardware.scaling import load_joints
from mover6_control.kinematics.arm import mover6
import numpy as np
import pytest
from sim_bridge.can_sim import build_arm, BusServer

ARM = mover6()
# The set-point discipline without referencing's hold (the joint file may say a joint needs no
# referencing; test_can_driver.py tests the hold and the referencing).
JOINTS = tuple(replace(j, reference_required=False) for j in load_joints()[1])
TICKS_PER_RAD = np.array([j.ticks_per_rad for j in JOINTS])
OFFSET = np.array([j.offset for j in JOINTS])
MAX_SPEED = np.array([j.max_speed for j in JOINTS])
STEP, CONTROL, CYCLE = 0.001, 0.01, 0.05        # [s] time step, control period, driver cycle
CHANNELS = itertools.count()
GOALS = [np.array([0.0, 0.3, -0.4, 0.0, 0.3, 0.0]),
         np.array([0.4, -0.3, 0.5, 0.2, -0.4, 0.3]),
         np.array([0.01, 0.002, -0.003, 0.0, 0.05, 0.0])]


class Loop:
    """Core, driver and CAN-level arm on one virtual bus; every event at its time."""

    def __init__(self, jog_units, phase, reading_delay, command_delay):
        self.t = 0.0
        self.units = jog_units
        self.reading_delay, self.command_delay = reading_delay, command_delay
        channel = f'can_settle_test_{next(CHANNELS)}'
        self.arm = build_arm()
        self.buses = [can.Bus(interface='virtual', channel=channel) for _ in range(2)]
        self.server = BusServer(self.arm, self.buses[0], clock=lambda: self.t)
        self.driver = ArmDriver(self.buses[1], JOINTS, clock=lambda: self.t)
        self.core = ControllerCore(ARM, ControllerConfig(cycle_driver=True, jog_units=jog_units,
                                                         state_timeout=1.0))
        self.next_cycle, self.next_tick = phase, 0.0
        self.readings, self.commands = [], []      # (due [s], payload), in time order

    def run(self, duration):
        """Run every event due in the next ``duration`` [s]."""
        end = self.t + duration
        while self.t < end - 1e-9:
            self.t = round(self.t + STEP, 9)
            self.driver.send_due(self.t)          # the control thread: frames frame_gap apart
            self.server.poll(0.0)
            if self.t >= self.next_cycle - 1e-9:
                self.next_cycle += CYCLE
                report = self.driver.step(self.t)
                q = np.array([j.q for j in report.joints])
                if np.all(np.isfinite(q)):
                    qd = np.array([j.qd for j in report.joints])
                    self.readings.append((self.t + self.reading_delay, (q, qd)))
            while self.readings and self.readings[0][0] <= self.t + 1e-9:
                send_states(self.core, self.t, *self.readings.pop(0)[1])
            if self.t >= self.next_tick - 1e-9:
                self.next_tick += CONTROL
                jog = self.core.tick(self.t).jog
                if self.units == 'fraction_of_max':      # as the driver node reads it
                    jog = jog * MAX_SPEED * self.core.config.speed_override
                self.commands.append((self.t + self.command_delay, jog))
            while self.commands and self.commands[0][0] <= self.t + 1e-9:
                due, qd = self.commands.pop(0)
                self.driver.set_velocity(qd, due)

    def request(self, kind):
        """Ask the driver for ``kind`` and run until the modules confirm it."""
        req = self.driver.request(kind)
        while req.ok is None:
            self.run(CONTROL)
            assert self.t < 10.0, kind
        assert req.ok, req.reason

    def ticks(self):
        """Return the modules' encoder counts (6,) [ticks, offset removed]."""
        return self.arm.encoders() - OFFSET

    def close(self):
        """Shut both buses."""
        for bus in self.buses:
            bus.shutdown()


@pytest.mark.parametrize('jog_units, phase, reading_delay, command_delay',
                         [('rad_per_s', 0.013, 0.002, 0.001),
                          ('fraction_of_max', 0.047, 0.01, 0.002),
                          ('rad_per_s', 0.001, 0.003, 0.008)])
def test_every_joint_settles_within_one_tick_of_its_goal(jog_units, phase, reading_delay,
                                                         command_delay):
    loop = Loop(jog_units, phase, reading_delay, command_delay)
    try:
        loop.request('reset')
        loop.request('enable')
        loop.run(0.3)
        assert loop.core.state == 'idle', loop.core.status().message
        for goal in GOALS:
            motion = send_demand(loop.core, loop.t, goal[None, :])
            start = loop.t
            while loop.core.status().values.get('result') != 'arrived':
                loop.run(CONTROL)
                assert loop.t < start + 20.0, loop.core.status().message
            arrived = loop.t
            while loop.core.state != 'idle':
                loop.run(CONTROL)
                assert loop.t < arrived + 5.0, loop.core.status().message
            message = loop.core.status().message
            assert loop.core.motion_id == motion and 'settled' in message, message
            loop.run(0.3)                                # at rest: what is sent has landed
            error = loop.ticks() - goal * TICKS_PER_RAD  # [ticks]
            assert np.all(np.abs(error) <= 1.0), (error.round(3).tolist(), message)
            assert loop.driver.report.hold == ''
    finally:
        loop.close()
