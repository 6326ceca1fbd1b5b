"""Pictures: frame sampling of a recording, and real offscreen PNG and GIF output (EGL)."""

import os
import subprocess
import sys

from mover6_control.errors import InvalidInputError
import numpy as np
from PIL import Image
import pytest
from sim_bridge.render import resample
from source_tree import ROOT


def test_resample_interpolates_at_the_frame_rate():
    """Frames come every 1/fps from the first time, positions interpolated linearly."""
    times = np.array([0.0, 0.1, 0.3, 1.0])
    Q = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 3.0], [-1.0, 3.0]])
    t_frames, Q_frames = resample(times, Q, fps=10.0)
    np.testing.assert_allclose(t_frames, np.arange(11) / 10.0)
    np.testing.assert_allclose(Q_frames[0], Q[0])
    np.testing.assert_allclose(Q_frames[1], Q[1])
    np.testing.assert_allclose(Q_frames[2], [1.0, 2.0])
    np.testing.assert_allclose(Q_frames[-1], Q[-1])
    np.testing.assert_allclose(Q_frames[6], [1.0 - 2.0 * 3.0 / 7.0, 3.0])


@pytest.mark.parametrize('times,Q,fps', [
    ([0.0, 0.0], [[0.0], [1.0]], 10.0),
    ([0.0, 1.0], [[0.0], [float('nan')]], 10.0),
    ([0.0, 1.0], [[0.0]], 10.0),
    ([0.0, 1.0], [[0.0], [1.0]], 0.0),
    ([], np.zeros((0, 6)), 10.0),
])
def test_resample_refuses_bad_recordings(times, Q, fps):
    """Non-increasing times, NaN, mismatched lengths, a bad fps or nothing: refused."""
    with pytest.raises(InvalidInputError):
        resample(times, Q, fps)


def test_png_and_gif_render_offscreen(tmp_path):
    """The command line writes a PNG of a pose and a GIF of a simulated motion, headless."""
    env = {k: v for k, v in os.environ.items() if k not in ('MUJOCO_GL', 'DISPLAY')}
    env['PYTHONPATH'] = ROOT + os.pathsep + env.get('PYTHONPATH', '')
    png, gif = tmp_path / 'arm.png', tmp_path / 'motion.gif'
    cmd = [sys.executable, '-m', 'sim_bridge.render', '--q', '0', '0.5', '0.4', '0', '0.8',
           '0', '--png', str(png), '--gif', str(gif), '--width', '160', '--height', '120',
           '--fps', '10']
    result = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    image = np.asarray(Image.open(png).convert('RGB')).astype(int)
    assert image.shape == (120, 160, 3)
    orange = (image[..., 0] > 150) & (image[..., 2] < 100)        # the arm's capsules
    assert 50 < orange.sum() < image.shape[0] * image.shape[1] // 2
    with Image.open(gif) as animation:
        assert animation.n_frames == 21                           # 2 s demo at 10 fps
        frames = []
        for k in (0, 5, 10):
            animation.seek(k)
            frames.append(np.asarray(animation.convert('RGB')).astype(int))
    assert np.abs(frames[0] - frames[1]).sum() > 0                # the arm moved
    assert np.abs(frames[1] - frames[2]).sum() > 0
