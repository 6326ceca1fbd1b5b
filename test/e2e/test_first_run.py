"""
The first-run check end to end on the simulated arm: ``first_run --can-sim --yes``.

``first_run`` starts ``can_sim`` (the CAN-level Mover6 on a pty) and the driver (enabled at
start) as processes, jogs each joint +5 deg at 10 % speed and back, answers yes (``--yes``: the
simulated arm counts with the same joint file, so its directions cannot be wrong), prints the
summary and writes the calibration file; the driver's check of that file finds nothing wrong.
"""

import math
import os
import subprocess
import sys
import time

from mover6_control.hardware.calibration import check_calibration, load_calibration
from mover6_control.hardware.scaling import load_joints
import pytest

pytestmark = pytest.mark.e2e


def test_first_run_on_can_sim(tmp_path):
    output = tmp_path / 'calibration.yaml'
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, '-m', 'mover6_control.tools.first_run', '--can-sim', '--yes',
         '--output', str(output)], capture_output=True, text=True, timeout=300,
        env=dict(os.environ))
    took = time.monotonic() - start
    assert run.returncode == 0, run.stdout + run.stderr
    assert 'first_run summary:' in run.stdout
    _, joints = load_joints()
    calibration = load_calibration(str(output))
    assert sorted(calibration) == [j.name for j in joints]
    for j in joints:
        c = calibration[j.name]
        assert c.sign_confirmed and c.scale_confirmed and c.gear == j.gear
        assert abs(c.angle_moved_deg - 5.0) < 0.5, (j.name, c)
        assert c.ticks_moved == pytest.approx(
            math.radians(c.angle_moved_deg) * j.ticks_per_rad, abs=2)
        assert f'{j.name}: direction confirmed, angle confirmed' in run.stdout
    assert check_calibration(calibration, joints) == ([], [])
    print(run.stdout)
    print(f'FIGURE first_run: six joints +5 deg and back on can_sim in {took:.1f} s')
