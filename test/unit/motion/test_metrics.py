"""Trajectory metrics: exact figures on trajectories whose answers are known in closed form."""

from hypothesis import assume, given, settings
import hypothesis.strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.motion import metrics
from mover6_control.motion.timing import time_laws as tl
from mover6_control.motion.timing.trajectories import TimeLawTrajectory
import numpy as np
import pytest


def test_distance_to_polyline_by_geometry():
    poly = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    assert metrics.max_deviation_from_polyline([[0.5, -0.3, 0.0]], poly) == pytest.approx(0.3)
    assert metrics.max_deviation_from_polyline([[-1.0, 0.0, 0.0]], poly) == pytest.approx(1.0)
    assert metrics.max_deviation_from_polyline([[1.5, 0.5, 0.4]], poly) == pytest.approx(
        np.hypot(0.5, 0.4))
    assert metrics.max_deviation_from_polyline([[0, 0, 3.0]], poly[:1]) == pytest.approx(3.0)
    pts = [[0.2, 0.0, 0.0], [1.0, 0.7, 0.0], [0.5, 0.5, 0.0]]
    assert metrics.max_deviation_from_polyline(pts, poly) == pytest.approx(0.5)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.floats(0.0, 1.0),
       st.floats(0.0, 0.5))
def test_point_off_a_segment_by_a_known_distance(a, b, t, off):
    a, b = np.array(a), np.array(b)
    d = b - a
    assume(np.linalg.norm(d) >= 1e-3)             # a segment, not a point
    normal = np.cross(d, [1.0, 0.0, 0.0])
    if np.linalg.norm(normal) < 1e-3 * np.linalg.norm(d):
        normal = np.cross(d, [0.0, 1.0, 0.0])
    normal /= np.linalg.norm(normal)
    p = a + t * d + off * normal
    assert metrics.max_deviation_from_polyline([p], [a, b]) == pytest.approx(off, abs=1e-9)


def test_cubic_move_metrics_are_exact():
    q0, q1, T = np.array([0.0, 0.2, -0.1]), np.array([1.0, -0.2, 0.3]), 2.0
    traj = TimeLawTrajectory(q0, q1, T, tl.cubic())
    m = metrics.trajectory_metrics(traj, dt=1e-3)
    dq = np.abs(q1 - q0)
    assert m.duration == T
    assert np.allclose(m.peak_velocity, 1.5 * dq / T)          # s' peaks at 1.5
    assert np.allclose(m.peak_acceleration, 6.0 * dq / T ** 2)  # s'' peaks at 6 at the ends
    assert np.allclose(m.peak_jerk, 12.0 * dq / T ** 3)         # s''' = -12 throughout
    assert m.joint_path_length == pytest.approx(np.linalg.norm(q1 - q0))
    assert np.isnan(m.path_length) and np.isnan(m.max_deviation)


def test_cartesian_figures_with_a_fake_fk():
    # 'FK' = the first three joints as a point: the tool moves on the segment q0 -> q1.
    q0, q1 = np.array([0.0, 0.0, 0.0, 0.5]), np.array([0.3, 0.4, 0.0, -0.5])
    traj = TimeLawTrajectory(q0, q1, 1.0, tl.quintic())

    def fk_fn(Q):
        return Q[:, :3]

    m = metrics.trajectory_metrics(traj, fk_fn, desired_positions=[q0[:3], q1[:3]], dt=1e-3)
    assert m.path_length == pytest.approx(0.5)
    assert m.max_deviation == pytest.approx(0.0, abs=1e-12)
    shifted = [q0[:3] + [0, 0, 0.01], q1[:3] + [0, 0, 0.01]]
    m = metrics.trajectory_metrics(traj, fk_fn, desired_positions=shifted)
    assert m.max_deviation == pytest.approx(0.01)


def test_sample_times_include_the_end():
    t = metrics.sample_times(1.0025, 1e-3)
    assert t[0] == 0.0 and t[-1] == 1.0025 and np.all(np.diff(t) <= 1e-3 + 1e-15)


def test_bad_input_raises():
    traj = TimeLawTrajectory([0.0], [1.0], 1.0, tl.cubic())
    with pytest.raises(InvalidInputError):
        metrics.trajectory_metrics(traj, dt=0.0)
    with pytest.raises(InvalidInputError):
        metrics.trajectory_metrics(traj, desired_positions=[[0, 0, 0], [1, 0, 0]])
    with pytest.raises(InvalidInputError):
        metrics.trajectory_metrics(traj, fk_fn=lambda Q: Q, desired_positions=[[0, 0, 0]])
    with pytest.raises(InvalidInputError):
        metrics.max_deviation_from_polyline(np.zeros((0, 3)), [[0, 0, 0]])
    with pytest.raises(InvalidInputError):
        metrics.max_deviation_from_polyline([[np.nan, 0, 0]], [[0, 0, 0]])
