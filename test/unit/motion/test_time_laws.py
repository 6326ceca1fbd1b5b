"""Time laws s(tau): boundary conditions, derivatives, the numbers of the source documents."""

from hypothesis import given, settings
import hypothesis.strategies as st
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.errors import InvalidInputError
from mover6_control.motion.timing import time_laws as tl
from mover6_control.motion.timing.trajectories import TimeLawTrajectory
import numpy as np
import pytest

TAU = np.linspace(0.0, 1.0, 20001)
ALL = [tl.cubic(), tl.quintic(), tl.septic(), tl.trapezoidal(), tl.sharp_trapezoid()]


@pytest.mark.parametrize('law', ALL, ids=lambda law: law.name)
def test_rest_to_rest_from_zero_to_one(law):
    assert law(0.0) == pytest.approx(0.0, abs=1e-12)
    assert law(1.0) == pytest.approx(1.0, abs=1e-12)
    assert law.evaluate(0.0, 1) == pytest.approx(0.0, abs=1e-12)
    assert law.evaluate(1.0, 1) == pytest.approx(0.0, abs=1e-12)
    assert np.all(law.evaluate(TAU, 1) >= -1e-12)          # never moves backwards


@pytest.mark.parametrize('law', ALL, ids=lambda law: law.name)
def test_derivatives_match_finite_differences(law):
    h = TAU[1] - TAU[0]
    for k in (1, 2):
        numeric = np.gradient(law.evaluate(TAU, k - 1), h)
        analytic = law.evaluate(TAU, k)
        inner = slice(2, -2)
        # Trapezoids have kinks in s'; compare away from them.
        ok = np.abs(numeric - analytic)[inner] < 1e-6 * max(1.0, np.abs(analytic).max())
        assert ok.mean() > 0.999


def test_higher_order_end_conditions():
    q, s = tl.quintic(), tl.septic()
    for tau in (0.0, 1.0):
        assert q.evaluate(tau, 2) == pytest.approx(0.0, abs=1e-12)
        assert s.evaluate(tau, 2) == pytest.approx(0.0, abs=1e-12)
        assert s.evaluate(tau, 3) == pytest.approx(0.0, abs=1e-12)
    assert q.coefficients == (0.0, 0.0, 0.0, 10.0, -15.0, 6.0)
    assert tl.cubic().coefficients == (0.0, 0.0, 3.0, -2.0)
    assert s.coefficients[4:] == (35.0, -84.0, 70.0, -20.0)


def test_jacobians_report_via_point_polynomial_coefficients():
    S = tl.via_fraction(83.14, 90.0, 173.37)
    assert S == pytest.approx(0.0760279, abs=1e-7)
    law = tl.via_point_polynomial(S)
    c = np.array(law.coefficients)
    assert np.allclose(c[:3], 0.0, atol=1e-12)
    assert np.round(c[3:], 2).tolist() == [-17.13, 66.40, -75.40, 27.13]
    assert law(0.5) == pytest.approx(S, abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.5, 1.5), st.floats(0.05, 0.95))
def test_via_point_polynomial_meets_all_seven_conditions(s_via, tau_via):
    law = tl.via_point_polynomial(s_via, tau_via)
    assert law(0.0) == pytest.approx(0.0, abs=1e-9)
    assert law(1.0) == pytest.approx(1.0, abs=1e-9)
    for tau in (0.0, 1.0):
        for k in (1, 2):
            assert law.evaluate(tau, k) == pytest.approx(0.0, abs=1e-7)
    assert law(tau_via) == pytest.approx(s_via, abs=1e-9)


def test_mover6_report_trapezoid_eq16_to_18():
    t_max, dq = 2.0, 0.8
    law = tl.trapezoidal(t_max)
    assert law.blend == pytest.approx(0.25)
    traj = TimeLawTrajectory([0.0], [dq], t_max, law)
    v_max = dq / (t_max - t_max / 4.0)                     # eq. 16
    t_blend = t_max / 4.0
    for t in (0.3 * t_blend, 0.9 * t_blend):              # eq. 18, ramp up
        assert traj.sample(t)[1][0] == pytest.approx(v_max / t_blend * t)
    assert traj.sample(0.5 * t_max)[1][0] == pytest.approx(v_max)
    t = t_max - 0.5 * t_blend                              # ramp down
    assert traj.sample(t)[1][0] == pytest.approx(
        v_max * (1.0 - (t - (t_max - t_blend)) / t_blend))
    assert traj.sample(t_max)[0][0] == pytest.approx(dq)  # eq. 19


def test_sharp_trapezoid_is_three_equal_thirds():
    law = tl.sharp_trapezoid()
    assert law.evaluate(0.5, 1) == pytest.approx(1.5)
    assert law.evaluate(1.0 / 6.0, 1) == pytest.approx(0.75)
    assert law.evaluate(0.5, 2) == 0.0
    assert law.evaluate(0.1, 2) == pytest.approx(4.5)


@pytest.mark.parametrize('t_max, t_blend', [
    (1.0, 0.5), (1.0, 0.6), (1.0, 0.0), (1.0, -0.1), (0.0, None), (-1.0, None),
    (1.0, float('nan')), (float('inf'), None)])
def test_trapezoid_rejects_bad_blend(t_max, t_blend):
    with pytest.raises(InvalidInputError):
        tl.trapezoidal(t_max, t_blend)


def test_trapezoid_times_default_and_bounds():
    """The one check of the Mover6 report's trapezoid: t_blend = t_max / 4 by default."""
    assert tl.trapezoid_times(2.0) == (2.0, 0.5)
    assert tl.trapezoid_times(2.0, 0.3) == (2.0, 0.3)
    with pytest.raises(InvalidInputError, match='t_blend'):
        tl.trapezoid_times(1.0, 0.5)
    with pytest.raises(InvalidInputError, match='t_max'):
        tl.trapezoid_times(0.0)


def test_one_trapezoid_for_the_joint_the_robot_and_the_velocity_law():
    """The controller's trapezoidal profile plays ``time_laws.trapezoidal`` on every joint."""
    t_max, t_blend, dq = 1.6, 0.3, 0.4
    law = tl.trapezoidal(t_max, t_blend)
    q1 = np.array([dq, -dq, 0.0, 0.1, 0.0, 0.0])
    plan = plan_motion(LawConfig(profile='trapezoidal', t_max=t_max, t_blend=t_blend),
                       np.zeros(6), q1[None], np.full(6, 10.0))
    for t in np.linspace(0.0, t_max, 41)[:-1]:
        rate = law.evaluate(t / t_max, 1) / t_max
        np.testing.assert_allclose(plan.sample(t)[1], q1 * rate, atol=1e-15)
        np.testing.assert_allclose(plan.sample(t)[0], q1 * law.evaluate(t / t_max), atol=1e-15)


def test_bad_input_is_rejected():
    with pytest.raises(InvalidInputError):
        tl.via_point_polynomial(0.1, 1.0)
    with pytest.raises(InvalidInputError):
        tl.via_fraction(1.0, 2.0, 1.0)
    with pytest.raises(InvalidInputError):
        tl.by_name('sinusoid')
    with pytest.raises(InvalidInputError):
        tl.cubic()(float('nan'))
    assert tl.by_name('trapezoidal', t_max=2.0, t_blend=0.2).blend == pytest.approx(0.1)


def test_tau_is_clamped_outside_zero_one():
    law = tl.quintic()
    assert law(-1.0) == 0.0 and law(2.0) == 1.0
