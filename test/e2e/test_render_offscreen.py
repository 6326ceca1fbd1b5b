"""Pictures: real offscreen PNG and GIF output (EGL) of the render command line, a process."""

import os
import subprocess
import sys

import numpy as np
from PIL import Image
from source_tree import ROOT


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
