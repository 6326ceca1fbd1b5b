"""
End to end on the CAN-level Mover6: the driver's lifecycle walked as a user walks it.

``can_sim`` (six simulated motor modules on a pty, as on /dev/ttyUSB0) and the driver on that pty
(``enable_on_start`` false: it configures itself at start and stays inactive), each a process;
the lifecycle is walked with ``ros2 lifecycle get`` and ``ros2 lifecycle set`` as processes of
their own (``test/lifecycle_cli.py``: ros2cli's calls and output; the ROS 2 wheels here carry no
ros2cli). After each step the simulated modules say what the transition did to the arm: enabled
and referenced by activate (J2 parked away from its switch, so referencing is seen to move it,
and how long it took), disabled by deactivate and by shutdown; a transition out of
order is refused with the transitions the state has. Everything said is printed, as a transcript.
"""

import os
import subprocess
import sys
import time

import numpy as np
import pytest
from ros_testing import CanSimProcess, ROOT, Stack, wait_until
from sim_bridge.can_arm import ModuleTiming

pytestmark = pytest.mark.e2e

CLI = [sys.executable, os.path.join(ROOT, 'test', 'lifecycle_cli.py')]
PARKED = [0.0, 0.3, 0.0, 0.0, 0.0, 0.0]          # [rad] J2 away from its switch (angle 0)


class Transcript:
    """Run ``ros2 lifecycle`` commands; keep every command and its output."""

    def __init__(self):
        self.lines = []

    def run(self, *words):
        """Run one command; return (exit code, its stdout and stderr as one text, seconds)."""
        start = time.monotonic()
        done = subprocess.run(CLI + list(words), capture_output=True, text=True, timeout=300)
        took = time.monotonic() - start
        out = (done.stdout + done.stderr).strip()
        self.lines.append(f'$ ros2 lifecycle {" ".join(words)}    # {took:.1f} s\n{out}')
        return done.returncode, out, took

    def text(self):
        """Return the transcript."""
        return '\n'.join(self.lines)


def modules(sim):
    """Return the simulated modules' states (enabled, referenced, ...)."""
    return sim.control('status')['modules']


def test_the_lifecycle_walked_with_the_cli(tmp_path):
    cli = Transcript()
    home = [str(q) for q in PARKED]
    with CanSimProcess(tmp_path, tmp_path / 'mover6-can', ['--home', *home]) as sim:
        driver = {'can_interface': 'cpr_usb2can', 'can_channel': sim.link,
                  'enable_on_start': False}
        with Stack(tmp_path, driver=driver, names=('driver',)) as stack:
            try:
                walk(cli, sim, stack)
            finally:
                print(cli.text())
                (tmp_path / 'lifecycle_transcript.txt').write_text(cli.text() + '\n')


def walk(cli, sim, stack):
    """Walk the lifecycle on ``sim`` and ``stack`` (``cli`` keeps the transcript)."""
    assert wait_until(lambda: cli.run('get', '/driver')[1] == 'inactive [2]', 60.0), \
        f'{cli.text()}\n{stack.report()}'
    assert not any(m['enabled'] for m in modules(sim))     # configured: nothing enabled
    q0 = np.array(sim.control('status')['q'])
    assert np.allclose(q0, PARKED, atol=1e-3), q0           # nothing moved

    code, out, took = cli.run('set', '/driver', 'configure')   # out of order
    assert out.startswith('Unknown transition requested') and '- activate [3]' in out, out

    code, out, took = cli.run('set', '/driver', 'activate')
    assert out == 'Transitioning successful', f'{out}\n{stack.report()}'
    assert cli.run('get', '/driver')[1] == 'active [3]'
    status = modules(sim)
    assert all(m['enabled'] for m in status)
    assert [m['referenced'] for m in status] == [True] * 4 + [False] * 2
    q1 = np.array(sim.control('status')['q'])
    assert abs(q1[1]) < 0.01, q1                             # J2 drove to its switch
    timing = ModuleTiming()
    least = PARKED[1] / timing.reference_speed + 4 * timing.reference_time
    print(f'activate took {took:.1f} s: reset, enable, J1..J4 referenced in order; J2 drove '
          f'{PARKED[1]} rad to its switch at {timing.reference_speed} rad/s')
    assert took >= least, (took, least)

    code, out, took = cli.run('set', '/driver', 'deactivate')
    assert out == 'Transitioning successful', f'{out}\n{stack.report()}'
    assert cli.run('get', '/driver')[1] == 'inactive [2]'
    assert not any(m['enabled'] for m in modules(sim))

    code, out, took = cli.run('set', '/driver', 'cleanup')
    assert out == 'Transitioning successful', out
    assert cli.run('get', '/driver')[1] == 'unconfigured [1]'

    code, out, took = cli.run('set', '/driver', 'activate')    # out of order
    assert out.startswith('Unknown transition requested') and '- configure [1]' in out, out
    assert cli.run('get', '/driver')[1] == 'unconfigured [1]'

    for transition, state in (('configure', 'inactive [2]'), ('activate', 'active [3]'),
                              ('shutdown', 'finalized [4]')):
        code, out, took = cli.run('set', '/driver', transition)
        assert out == 'Transitioning successful', f'{transition}: {out}\n{stack.report()}'
        assert cli.run('get', '/driver')[1] == state
    assert not any(m['enabled'] for m in modules(sim))
    assert stack.nodes['driver'].alive()                     # finalized, not ended
