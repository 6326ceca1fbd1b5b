"""
The sim_bridge node parts, each built alone: ``PhysicsThread``, ``SimControls``, ``SimJogIntake``.

A real ``Simulator`` (MuJoCo) under each; the publishers are recording stand-ins (the node's
are rclpy's, exercised by ``test_sim_node.py``), and the physics thread is never started: the
test runs its steps (``catch_up`` unpaced runs a whole batch) in its own thread.
"""

from control_msgs.msg import JointJog
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.messages import cdr
from mover6_control.values import JogRequest
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from sim_bridge.bridge_controls import SimControls
from sim_bridge.bridge_node import SimJogIntake
from sim_bridge.bridge_physics import (BridgeOutputs, MAX_BATCH, Pacing, PhysicsThread,
                                       Rejections)
from sim_bridge.simulator import SimConfig, Simulator

ARM = mover6()
NAMES = list(ARM.joint_names)


class Recorder:
    """A publisher that keeps what it is given."""

    def __init__(self):
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)


class Log:
    """A logger that keeps its lines by level."""

    def __init__(self):
        self.lines = []

    def __getattr__(self, level):
        return lambda text, **kwargs: self.lines.append((level, text))


def build(publish_period=0.01, rest_period=None, clock=True):
    """Return (physics, outputs) on a fresh simulator, unpaced, sim-time stamps."""
    sim = Simulator(ARM, SimConfig(command_timeout=2.0))   # a command holds for the test
    pacing = Pacing(dt=sim.config.physics_dt, rtf=0.0, publish_period=publish_period,
                    rest_period=rest_period or publish_period, publish_clock=clock)
    outputs = BridgeOutputs(Log(), Recorder(), Recorder(), Recorder(),
                            Recorder() if clock else None, cdr.JointStateWriter(NAMES),
                            node_clock=None, sim_stamps=True)
    return PhysicsThread(sim, pacing, outputs, Rejections()), outputs


def stamps(outputs):
    """Return the stamps [s] of the /joint_states published."""
    msgs = [deserialize_message(raw, JointState) for raw in outputs.joint_states.sent]
    return np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs])


def test_physics_steps_and_publishes_on_its_schedule():
    """Unpaced, one catch_up runs a batch: a /clock per step, /joint_states every period."""
    physics, outputs = build()
    with physics.step_lock:
        assert physics.catch_up() is False              # unpaced: never an overrun
    dt = physics.pacing.dt
    assert physics.sim.time == pytest.approx(MAX_BATCH * dt)
    assert len(outputs.clock.sent) == MAX_BATCH
    t = stamps(outputs)
    assert len(t) == pytest.approx(MAX_BATCH * dt / 0.01, abs=1)
    np.testing.assert_allclose(np.diff(t[1:]), 0.01, atol=dt / 2)   # the first: at step 1
    physics.report_status(0.0)
    assert outputs.status.sent[-1].message.startswith('running')


def test_rest_period_at_rest_and_the_full_rate_from_a_command():
    """At rest /joint_states every rest period; a command brings the full rate at once."""
    physics, outputs = build(publish_period=0.01, rest_period=0.05)
    with physics.step_lock:
        physics.catch_up()
    np.testing.assert_allclose(np.diff(stamps(outputs)[1:]), 0.05, atol=1e-6)
    physics.command(JogRequest(tuple(NAMES), (0.2, 0.0, 0.0, 0.0, 0.0, 0.0)), arrival=0.0)
    before = len(outputs.joint_states.sent)
    with physics.step_lock:
        physics.catch_up()
    moving = stamps(outputs)[before:]                 # the first: one period after it, or sooner
    np.testing.assert_allclose(np.diff(moving[1:]), 0.01, atol=1e-6)
    assert len(physics.latencies) == 1                 # its first step came
    physics.set_periods(publish_period=0.02)          # live: from the next publication on
    before = len(outputs.joint_states.sent)
    with physics.step_lock:
        physics.catch_up()
    np.testing.assert_allclose(np.diff(stamps(outputs)[before:][1:]), 0.02, atol=1e-6)


def test_controls_pause_step_and_reset():
    """The controls on a physics thread: pause, one period per step, reset to named positions."""
    physics, outputs = build()
    controls = SimControls(physics, NAMES, Log())
    t = controls.pause(True)
    assert physics.paused and t == physics.sim.time
    with physics.step_lock:
        physics.catch_up()                              # paused: no steps
    assert physics.sim.time == t
    n = controls.step_period()
    assert n == round(0.01 / physics.pacing.dt)
    assert physics.sim.time == pytest.approx(t + 0.01)
    assert stamps(outputs)[-1] == pytest.approx(physics.sim.time)
    q = controls.named_positions(['joint2'], [0.3])
    controls.reset_to(q)
    last = deserialize_message(outputs.joint_states.sent[-1], JointState)
    np.testing.assert_allclose(last.position, [0.0, 0.3, 0.0, 0.0, 0.0, 0.0], atol=1e-9)
    with pytest.raises(InvalidInputError):
        controls.named_positions(['elbow'], [0.3])
    with pytest.raises(InvalidInputError):
        controls.named_positions(['joint1', 'joint2'], [0.3])


def jog(names, velocities):
    """Return a serialized JointJog."""
    return serialize_message(JointJog(joint_names=list(names),
                                      velocities=[float(v) for v in velocities]))


def test_jog_intake_hands_commands_over_and_counts_refusals():
    """A JointJog moves the simulated arm; a bad one is refused, counted, changes nothing."""
    physics, _ = build()
    rejections = physics.rejections
    intake = SimJogIntake(physics, rejections, Log())
    intake.take(jog(NAMES, [0.2, 0, 0, 0, 0, 0]))
    assert physics.pending is not None
    with physics.step_lock:
        physics.catch_up()
    assert physics.sim.state().q[0] > 0.0
    count = physics.sim.command_count
    with pytest.raises(InvalidInputError):
        intake.take(jog(['joint1', 'elbow'], [0.1, 0.1]))
    assert rejections.count == 1 and 'elbow' in rejections.last
    assert physics.sim.command_count == count
