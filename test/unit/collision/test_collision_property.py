"""
Property: a path the checker calls free never touches anything when the simulated arm runs it.

Seeded random paths inside the joint limits (a start and one or two waypoints) are checked
with the default settings (20 mm table margin, the default gripper); the free ones are run by
the controller core on the simulator (ROS-free: ``sim_bridge.simulator`` and
``control.controller_core`` driven directly, at 100 Hz), and MuJoCo's contact detection on the
same shapes (``Simulator.contact_steps``) must stay at zero. Paths the checker refuses are
counted too, so the property is not met by finding nothing free.
"""

from core_testing import send_demand, send_states
from mover6_control.collision.checker import CollisionChecker
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.state_machine import IDLE
from mover6_control.kinematics.arm import mover6
import numpy as np
from sim_bridge.simulator import Simulator

ARM = mover6('within_90_deg')
CHECKER = CollisionChecker(ARM)
RATE = 100.0
N_PATHS = 30


def run_on_simulator(sim, start, waypoints, max_time=30.0):
    """Run ``waypoints`` from ``start`` with the controller core; return the contact steps."""
    sim.reset(start)
    core = ControllerCore(ARM)
    per_tick = int(round(1.0 / RATE / sim.config.physics_dt))
    t = sim.time
    reading = sim.state()
    send_states(core, t, reading.q, reading.qd)
    core.tick(t)
    send_demand(core, t, waypoints)
    while sim.time - t < max_time:
        reading = sim.state()
        send_states(core, sim.time, reading.q, reading.qd)
        out = core.tick(sim.time)
        if out.state == IDLE:
            break
        sim.set_command(ARM.joint_names, out.qd, sim.time)
        sim.step(per_tick)
    return sim.contact_steps


def test_free_paths_touch_nothing_in_the_simulator():
    """Every free path runs without a contact; some random paths are refused on the way."""
    rng = np.random.default_rng(2024)
    sim = Simulator(ARM)
    free = refused = 0
    while free < N_PATHS:
        path = rng.uniform(ARM.lower, ARM.upper, (int(rng.integers(2, 4)), 6))
        if not CHECKER.check_path(path).free:
            refused += 1
            continue
        free += 1
        assert run_on_simulator(sim, path[0], path[1:]) == 0, path.tolist()
        assert np.allclose(sim.q, path[-1], atol=0.01)
    assert refused > 0


def test_a_refused_path_does_touch_in_the_simulator():
    """The other way round, so the property can fail: the checker's table refusal touches."""
    sim = Simulator(ARM)
    home = np.zeros(6)
    into_table = np.array([[0.0, 0.78, 0.59, 0.0, 0.2, 0.0]])   # tool 80 mm into the table
    assert not CHECKER.check_path(np.vstack([home, into_table])).free
    assert run_on_simulator(sim, home, into_table) > 0
    assert 'link6_tool' in sim.first_contact[1] and 'table' in sim.first_contact[1]
