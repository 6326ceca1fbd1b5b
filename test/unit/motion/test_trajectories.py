"""Joint trajectories: one sampling interface, waypoints hit, limits kept, bad input refused."""

from hypothesis import example, given, settings
import hypothesis.strategies as st
from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing import jerk_limited as jl
from mover6_control.motion.timing import spline_trajectories as sp
from mover6_control.motion.timing import time_laws as tl
from mover6_control.motion.timing import trajectories as tj
import numpy as np
import pytest

V = np.array([0.524, 0.524, 0.524, 0.524, 0.698, 1.745])
A = np.full(6, 1.0)
Q = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
              [0.3, -0.2, 0.4, 0.1, -0.3, 0.5],
              [0.5, 0.1, 0.2, -0.2, 0.0, 0.9],
              [0.2, 0.3, -0.1, 0.0, 0.4, 0.2]])


def dense(traj, n=8001):
    t = np.linspace(0.0, traj.duration, n)
    return (t,) + traj.sample(t)


def test_point_to_point_follows_jacobians_report_eq29_to_32():
    q0, q1 = np.array([0.1, -0.2]), np.array([0.5, 0.4])
    law, T = tl.quintic(), 2.0
    traj = tj.point_to_point(q0, q1, law, duration=T)
    tau = 0.3
    q, qd, qdd = traj.sample(tau * T)
    assert np.allclose(q, q0 + (q1 - q0) * law(tau))
    assert np.allclose(qd, (q1 - q0) * law.evaluate(tau, 1) / T)
    assert np.allclose(qdd, (q1 - q0) * law.evaluate(tau, 2) / T ** 2)
    assert np.allclose(traj.sample_jerk(tau * T), (q1 - q0) * law.evaluate(tau, 3) / T ** 3)


def test_point_to_point_duration_from_limits_is_tight():
    q0, q1 = np.zeros(6), Q[1]
    traj = tj.point_to_point(q0, q1, tl.cubic(), v_max=V, a_max=A)
    _, _, qd, qdd = dense(traj)
    ratio = max(np.max(np.abs(qd) / V), np.max(np.abs(qdd) / A))
    assert 0.999 < ratio <= 1.0 + 1e-9
    # the Mover6 report eq. 1-2: every joint finishes together
    assert np.allclose(traj.sample(traj.duration)[0], q1)


def test_sample_shapes_and_clamping():
    traj = sp.cubic_trajectory(Q, v_max=V, a_max=A)
    q, qd, qdd = traj.sample(0.5)
    assert q.shape == qd.shape == qdd.shape == (6,)
    q, qd, qdd = traj.sample(np.array([0.0, 0.5, 1.0]))
    assert q.shape == (3, 6)
    assert traj.n_joints == 6
    end = traj.sample(traj.duration + 10.0)
    assert np.allclose(end[0], Q[-1]) and np.allclose(end[1], 0.0)
    assert np.allclose(traj.sample(-5.0)[0], Q[0])
    with pytest.raises(InvalidInputError):
        traj.sample(float('nan'))


@pytest.mark.parametrize('build', [sp.cubic_trajectory, sp.quintic_trajectory])
def test_interpolating_splines_pass_through_waypoints_at_their_times(build):
    times = np.array([0.0, 1.5, 2.5, 4.0])
    traj = build(Q, times=times)
    assert traj.duration == pytest.approx(4.0)
    q, qd, qdd = traj.sample(times)
    assert np.allclose(q, Q, atol=1e-12)
    assert np.allclose(qd[[0, -1]], 0.0, atol=1e-12)
    if build is sp.quintic_trajectory:
        assert np.allclose(qdd[[0, -1]], 0.0, atol=1e-9)


@pytest.mark.parametrize('build', [sp.cubic_trajectory, sp.quintic_trajectory,
                                   sp.bspline_trajectory])
def test_limit_fitted_splines_keep_and_touch_the_limits(build):
    traj = build(Q, v_max=V, a_max=A)
    _, q, qd, qdd = dense(traj)
    ratio = max(np.max(np.abs(qd) / V), np.max(np.abs(qdd) / A))
    assert 0.99 < ratio <= 1.0
    assert np.allclose(q[[0, -1]], Q[[0, -1]], atol=1e-12)
    assert np.allclose(qd[[0, -1]], 0.0, atol=1e-12)


def test_bspline_stays_in_the_convex_hull_per_joint():
    traj = sp.bspline_trajectory(Q, duration=5.0)
    _, q, _, _ = dense(traj)
    assert np.all(q >= Q.min(axis=0) - 1e-12) and np.all(q <= Q.max(axis=0) + 1e-12)


def test_multipoint_trapezoid_is_linear_with_parabolic_blends():
    traj = sp.multipoint_trapezoidal(Q, V, A)
    t, q, qd, qdd = dense(traj, 20001)
    assert np.allclose(q[[0, -1]], Q[[0, -1]], atol=1e-9)
    assert np.allclose(qd[[0, -1]], 0.0, atol=1e-9)
    assert np.all(np.abs(qd) <= V * (1.0 + 1e-9))
    assert np.all(np.abs(qdd) <= A + 1e-9)
    # Acceleration is 0 (cruise) or +-a_max (blend): piecewise constant.
    mags = np.abs(qdd)
    assert np.all(np.isclose(mags, 0.0, atol=1e-9) | np.isclose(mags, 1.0))
    # The pieces join up: velocity is continuous (changes by at most a_max dt per sample) and
    # the position is the integral of the velocity.
    dt = t[1] - t[0]
    assert np.all(np.abs(np.diff(qd, axis=0)) <= A * dt * (1.0 + 1e-6))
    integ = Q[0] + np.concatenate([np.zeros((1, 6)), np.cumsum(
        (qd[1:] + qd[:-1]) * 0.5 * dt, axis=0)])
    assert np.allclose(q, integ, atol=1e-5)


def test_stop_at_each_rests_on_every_waypoint():
    traj = tj.stop_at_each(Q, tl.trapezoidal, V, A)
    q, qd, _ = traj.sample(traj.starts)
    assert np.allclose(q, Q, atol=1e-12)
    assert np.allclose(qd, 0.0, atol=1e-12)
    _, _, qd, qdd = dense(traj, 40001)
    assert np.all(np.abs(qd) <= V * (1.0 + 1e-9)) and np.all(np.abs(qdd) <= A * (1.0 + 1e-9))


def test_ruckig_is_jerk_limited_and_synchronised():
    j = np.full(6, 5.0)
    qd0 = np.array([0.2, -0.1, 0.0, 0.3, 0.0, -0.5])
    traj = jl.ruckig_trajectory(Q[0], Q[1], V, A, j, qd0=qd0)
    q, qd, qdd = traj.sample(0.0)
    assert np.allclose(qd, qd0) and np.allclose(qdd, 0.0)
    q, qd, qdd = traj.sample(traj.duration)
    assert np.allclose(q, Q[1], atol=1e-9) and np.allclose(qd, 0.0, atol=1e-9)
    t = np.linspace(0.0, traj.duration, 2001)
    _, qd, qdd = traj.sample(t)
    assert np.all(np.abs(qd) <= V + 1e-9) and np.all(np.abs(qdd) <= A + 1e-9)
    assert np.all(np.abs(traj.sample_jerk(t)) <= j * (1.0 + 1e-5))
    # Time-optimal: the slowest joint alone cannot do better.
    alone = [jl.ruckig_trajectory(Q[0, [i]], Q[1, [i]], V[i], A[i], j[i], qd0=qd0[[i]]).duration
             for i in range(6)]
    assert traj.duration == pytest.approx(max(alone), rel=1e-6)


def dense_with_breakpoints(traj, n=20001):
    """Sample ``traj`` on a uniform grid plus its breakpoints (where cubic accelerations peak)."""
    t = np.unique(np.concatenate([np.linspace(0.0, traj.duration, n), traj.breakpoints]))
    return traj.sample(t)


# Found by hypothesis: the velocity peak of the long second piece lay between the peak-search
# samples, so the fitted cubic reached |qd| = 1.0001 > v_max.
FOUND = [[0.0, 0.0, 0.5], [0.0, 0.0, 1.5], [0.0, 0.0, -1.75]]


@pytest.mark.parametrize('build', [sp.cubic_trajectory, sp.quintic_trajectory,
                                   sp.bspline_trajectory])
@settings(max_examples=25, deadline=None)
@given(st.lists(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), min_size=2,
                max_size=8))
@example(FOUND)
@example([[0.0, 0.0, 0.0], [0.0, 0.0, 1e-6], [0.0, 0.0, 2.0]])
@example([[0.0, 0.0, 0.0], [1.0, -1.0, 2.0], [1.01, -1.0, 2.0], [-2.0, 2.0, -2.0]])
def test_cubic_through_random_waypoints(build, rows):
    # Named for the cubic, where hypothesis found FOUND; quintic and B-spline share the fit.
    W = np.array(rows)
    if np.any(np.abs(np.diff(W, axis=0)).max(axis=1) < 1e-12):
        with pytest.raises(InvalidInputError):
            build(W, v_max=1.0)
        return
    traj = build(W, v_max=1.0, a_max=2.0)
    if build is not sp.bspline_trajectory:
        cubic = build is sp.cubic_trajectory
        knots = traj.derivative_splines[0][0].x if cubic else traj.breakpoints
        assert np.allclose(traj.sample(knots)[0], W, atol=1e-9)
    assert np.allclose(traj.sample([0.0, traj.duration])[0], W[[0, -1]], atol=1e-9)
    _, qd, qdd = dense_with_breakpoints(traj)
    assert np.all(np.abs(qd) <= 1.0) and np.all(np.abs(qdd) <= 2.0)
    # One limit is met (the durations are as short as the limits allow).
    assert max(np.abs(qd).max(), np.abs(qdd).max() / 2.0) > 0.99


def test_found_case_peaks_are_exact():
    # The exact peaks behind the limit fit agree with a very fine grid.
    traj = sp.cubic_trajectory(np.array(FOUND), v_max=1.0, a_max=2.0)
    _, qd, qdd = dense_with_breakpoints(traj, 400001)
    pv, pa = sp._peaks(traj)
    assert np.allclose(pv, np.abs(qd).max(axis=0), rtol=1e-9, atol=1e-12)
    assert np.allclose(pa, np.abs(qdd).max(axis=0), rtol=1e-9, atol=1e-12)
    assert pv.max() == pytest.approx(1.0, rel=1e-8)


@pytest.mark.parametrize('law', [tl.cubic(), tl.quintic(), tl.septic(), tl.trapezoidal(),
                                 tl.via_point_polynomial(0.6, 0.4)])
def test_law_peaks_are_not_underestimated(law):
    tau = np.linspace(0.0, 1.0, 1000001)
    sd, sdd = tj.law_peaks(law)
    assert sd >= np.abs(law.evaluate(tau, 1)).max() * (1.0 - 1e-12)
    assert sdd >= np.abs(law.evaluate(tau, 2)).max() * (1.0 - 1e-12)
    assert sd == pytest.approx(np.abs(law.evaluate(tau, 1)).max(), rel=1e-6)
    assert sdd == pytest.approx(np.abs(law.evaluate(tau, 2)).max(), rel=1e-6)


@pytest.mark.parametrize('call', [
    lambda: sp.cubic_trajectory(Q[:1], v_max=V),
    lambda: sp.cubic_trajectory(np.vstack([Q[:2], Q[1:2]]), v_max=V),
    lambda: sp.quintic_trajectory(np.where(Q == 0.5, np.nan, Q), v_max=V),
    lambda: sp.cubic_trajectory(Q, v_max=np.zeros(6)),
    lambda: sp.cubic_trajectory(Q, v_max=V, a_max=-1.0),
    lambda: sp.cubic_trajectory(Q),
    lambda: sp.cubic_trajectory(Q, times=[0.0, 1.0, 1.0, 2.0]),
    lambda: sp.multipoint_trapezoidal(Q, V, 0.0),
    lambda: sp.bspline_trajectory(Q, duration=-1.0),
    lambda: tj.point_to_point(Q[0], Q[0], tl.cubic(), v_max=V),
    lambda: tj.point_to_point(Q[0], Q[1], tl.cubic()),
    lambda: tj.stop_at_each(Q[:1], tl.cubic(), V),
    lambda: jl.ruckig_trajectory(Q[0], Q[1], V, A, np.zeros(6)),
    lambda: jl.ruckig_trajectory(Q[0], Q[1, :3], V, A, A),
])
def test_bad_input_raises(call):
    with pytest.raises(InvalidInputError):
        call()


@pytest.mark.parametrize('build', [sp.cubic_trajectory, sp.quintic_trajectory,
                                   sp.bspline_trajectory])
def test_long_spline_paths_keep_the_limits_at_every_knot(build):
    # A cubic's acceleration peaks exactly at knots, which a uniform time grid misses.
    W = np.cumsum(np.random.default_rng(2).normal(scale=0.05, size=(300, 6)), axis=0)
    traj = build(W, v_max=V, a_max=A)
    b = traj.breakpoints
    t = np.unique(np.concatenate([b, np.linspace(0.0, traj.duration, 50001),
                                  0.5 * (b[1:] + b[:-1])]))
    _, qd, qdd = traj.sample(t)
    assert np.all(np.abs(qd) <= V) and np.all(np.abs(qdd) <= A)


@pytest.mark.parametrize('build', [
    lambda: tj.TimeLawTrajectory(Q[0], Q[1], 2.0, tl.trapezoidal(2.0)),
    lambda: tj.TimeLawTrajectory(Q[0], Q[1], 2.0, tl.quintic()),
    lambda: jl.ruckig_trajectory(Q[0], Q[1], V, A, 5.0, qd0=np.full(6, 0.1)),
    lambda: sp.cubic_trajectory(Q, v_max=V, a_max=A),
])
def test_state_of_one_tick_is_the_sample(build):
    """``state(t)``, the controller's per-tick path, gives exactly ``sample(t)[:2]``."""
    traj = build()
    for t in np.concatenate([[-1.0], np.linspace(0.0, traj.duration, 37), [traj.duration + 1]]):
        q, qd = traj.state(t)
        q_s, qd_s, _ = traj.sample(t)
        np.testing.assert_array_equal(q, q_s)
        np.testing.assert_array_equal(qd, qd_s)
    with pytest.raises(InvalidInputError):
        traj.state(float('nan'))
