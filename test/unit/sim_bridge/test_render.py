"""
Pictures: frame sampling of a recording.

The offscreen PNG and GIF output (a process): test/e2e/test_render_offscreen.py.
"""

from mover6_control.errors import InvalidInputError
import numpy as np
import pytest
from sim_bridge.render import resample


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
