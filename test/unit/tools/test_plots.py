"""Plots: each writes a real PNG file and returns its path; bad shapes are refused."""

from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing import time_laws as tl
from mover6_control.tools import plots
import numpy as np
import pytest

PNG = b'\x89PNG\r\n\x1a\n'


def is_png(path):
    with open(path, 'rb') as f:
        head = f.read(8)
    return head == PNG


def test_time_law_plot(tmp_path):
    laws = [tl.cubic(), tl.quintic(), tl.septic(), tl.trapezoidal(), tl.sharp_trapezoid(),
            tl.via_point_polynomial(0.0760279)]
    out = plots.plot_time_law(laws, tmp_path / 'sub' / 'laws.png')
    assert out == str(tmp_path / 'sub' / 'laws.png') and is_png(out)
    assert is_png(plots.plot_time_law({'3-4-5': tl.quintic()}, tmp_path / 'one.png'))


def test_joint_and_path_plots(tmp_path):
    t = np.linspace(0.0, 2.0, 200)
    Q = np.sin(np.outer(t, np.arange(1, 7)))
    lower, upper = -np.ones(6) * 1.571, np.ones(6) * 1.571
    out = plots.plot_joint_trajectories(t, Q, lower, upper, tmp_path / 'joints.png',
                                        QD=np.cos(np.outer(t, np.arange(1, 7))), QDD=Q)
    assert is_png(out)
    assert is_png(plots.plot_joint_velocities(t, Q, np.full(6, 0.524), tmp_path / 'v.png'))
    desired = np.column_stack([np.linspace(0.345, 0.445, 20), np.zeros(20), np.full(20, 0.44)])
    realised = desired + 1e-4
    assert is_png(plots.plot_path_3d(desired, realised, tmp_path / 'p.png', waypoints=desired))


def test_bad_shapes_raise(tmp_path):
    with pytest.raises(InvalidInputError):
        plots.plot_path_3d(np.zeros((5, 2)), np.zeros((5, 3)), tmp_path / 'x.png')
    with pytest.raises(InvalidInputError):
        plots.plot_joint_trajectories(np.zeros(4), np.zeros((5, 6)), np.zeros(6), np.ones(6),
                                      tmp_path / 'y.png')
    with pytest.raises(InvalidInputError):
        plots.plot_time_law([], tmp_path / 'z.png')
