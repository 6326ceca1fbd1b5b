"""The timed plan of FollowJointTrajectory goals: each point at its time_from_start."""

from core_testing import send_demand, send_states
from mover6_control.control.planners import plan_motion
from mover6_control.control.profiles import LawConfig
from mover6_control.control.timed_plan import (hermite_coefficients, peak, plan_demand,
                                               START_TOLERANCE, timed_plan, Timing, TimingError)
from mover6_control.errors import InvalidInputError
import numpy as np
import pytest
from scipy.interpolate import PPoly

N = 6
VLIM = np.full(N, 1.0)
A_MAX = 1.0
Q0 = np.zeros(N)
LAW = LawConfig()


def rows(*values):
    """Return waypoints (k, 6) moving joint 1 (and joint 2 by half) through ``values``."""
    return np.array([[v, v / 2.0, 0.0, 0.0, 0.0, 0.0] for v in values])


def test_points_are_reached_at_their_times():
    """Positions only: each point at its time_from_start, at rest at the start and the end."""
    Q = rows(0.2, 0.5)
    plan = timed_plan(Q0, Q, Timing([2.0, 4.0]), VLIM, A_MAX)
    assert plan.duration == pytest.approx(4.0)
    np.testing.assert_allclose(plan.sample(0.0)[0], Q0, atol=1e-12)
    np.testing.assert_allclose(plan.sample(0.0)[1], 0.0, atol=1e-12)
    np.testing.assert_allclose(plan.sample(2.0)[0], Q[0], atol=1e-9)
    np.testing.assert_allclose(plan.sample(4.0 - 1e-9)[0], Q[1], atol=1e-6)
    np.testing.assert_allclose(plan.sample(4.0 - 1e-9)[1], 0.0, atol=1e-6)
    assert plan.waypoints_reached(1.9) == 0 and plan.waypoints_reached(2.0) == 1
    np.testing.assert_allclose(plan.waypoint_times, [2.0, 4.0])
    # Not the time-optimal law's pace: that one is over long before.
    assert plan_motion(LAW, Q0, Q, VLIM).duration < 2.5


def test_velocities_are_honoured_cubic_hermite():
    """Positions and velocities: the reference passes each point with its velocity."""
    Q = rows(0.3, 0.6)
    V = np.array([[0.2, 0.1, 0, 0, 0, 0], [0.0] * N])
    plan = timed_plan(Q0, Q, Timing([1.5, 3.0], V), VLIM, A_MAX)
    q, qd = plan.sample(1.5)
    np.testing.assert_allclose(q, Q[0], atol=1e-9)
    np.testing.assert_allclose(qd, V[0], atol=1e-9)


def test_accelerations_are_honoured_quintic_hermite():
    """Positions, velocities and accelerations: quintic pieces match all three at the points."""
    Q = rows(0.3, 0.6)
    V = np.array([[0.2, 0.1, 0, 0, 0, 0], [0.0] * N])
    A = np.array([[0.05, 0.0, 0, 0, 0, 0], [0.0] * N])
    plan = timed_plan(Q0, Q, Timing([1.5, 3.0], V, A), VLIM, A_MAX)
    spline = plan.segments[0].spline
    np.testing.assert_allclose(spline(1.5), Q[0], atol=1e-9)
    np.testing.assert_allclose(spline.derivative(1)(1.5), V[0], atol=1e-9)
    np.testing.assert_allclose(spline.derivative(2)(1.5), A[0], atol=1e-9)
    np.testing.assert_allclose(spline.derivative(2)(0.0), 0.0, atol=1e-9)


def test_hermite_pieces_match_their_ends():
    """Each piece's coefficients give its end values (cubic and quintic)."""
    rng = np.random.default_rng(1)
    q0, v0, q1, v1, a0, a1 = (rng.normal(size=(2, 3)) for _ in range(6))
    h = np.array([0.7, 1.3])
    for accel in (False, True):
        c = hermite_coefficients(h, q0, v0, q1, v1, *((a0, a1) if accel else ()))
        for k in range(2):
            piece = PPoly(c[:, k:k + 1, :], [0.0, h[k]])
            np.testing.assert_allclose(piece(0.0), q0[k], atol=1e-12)
            np.testing.assert_allclose(piece(h[k]), q1[k], atol=1e-9)
            np.testing.assert_allclose(piece.derivative()(h[k]), v1[k], atol=1e-9)
            if accel:
                np.testing.assert_allclose(piece.derivative(2)(h[k]), a1[k], atol=1e-9)


def test_starts_from_the_commanded_velocity():
    """A goal that preempts a motion starts from its velocity: the command does not jump."""
    qd_start = np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    plan = timed_plan(Q0, rows(0.5), Timing([3.0]), VLIM, A_MAX, qd_start)
    np.testing.assert_allclose(plan.sample(0.0)[1], qd_start, atol=1e-12)


def test_first_point_at_zero_is_the_start():
    """A first point at time 0 (MoveIt's start state) is passed over; too far is refused."""
    Q = np.vstack([Q0 + 0.002, rows(0.4)])
    plan = timed_plan(Q0, Q, Timing([0.0, 3.0]), VLIM, A_MAX)
    np.testing.assert_allclose(plan.sample(0.0)[0], Q0, atol=1e-12)   # no jump
    np.testing.assert_allclose(plan.sample(3.0 - 1e-9)[0], Q[-1], atol=1e-6)
    assert plan.waypoints_reached(0.0) == 1
    far = np.vstack([Q0 + 2 * START_TOLERANCE, rows(0.4)])
    with pytest.raises(TimingError, match='first point'):
        timed_plan(Q0, far, Timing([0.0, 3.0]), VLIM, A_MAX)


@pytest.mark.parametrize('times, velocities, match', [
    ([1.0, 1.0], None, 'increase strictly'),
    ([0.3, 0.6], None, 'joint 1 speed'),
    ([1.0, 1.4], None, 'joint 1 acceleration'),
    ([2.0, 4.0], [[0.0] * N, [0.1] + [0.0] * (N - 1)], 'non-zero velocities'),
])
def test_timing_that_cannot_be_followed_says_why(times, velocities, match):
    """Repeated times, too fast, too abrupt, not at rest at the end: TimingError, reason."""
    with pytest.raises(TimingError, match=match):
        timed_plan(Q0, rows(0.5, 1.0), Timing(times, velocities), VLIM, A_MAX)


def test_position_limits_between_the_points():
    """A velocity that swings a joint past its limit between points is refused."""
    V = np.array([[1.0, 0, 0, 0, 0, 0], [0.0] * N])
    upper = np.full(N, 0.45)
    with pytest.raises(TimingError, match='outside its limits'):
        timed_plan(Q0, rows(0.4, 0.4), Timing([1.0, 2.0], V), np.full(N, 5.0), 10.0,
                   lower=-upper, upper=upper)


def test_peaks_are_exact_not_sampled():
    """The peak speed of a rest-to-rest cubic is 1.5 times the mean speed, to rounding."""
    plan = timed_plan(Q0, rows(0.6), Timing([2.0]), VLIM, A_MAX)
    lo, hi = peak(plan.segments[0].spline, 1, 0)
    assert hi == pytest.approx(1.5 * 0.6 / 2.0, rel=1e-12) and lo == pytest.approx(0.0, abs=1e-12)


def test_plan_demand_follows_or_falls_back():
    """Untimed: the law's plan; timed within limits: as given; beyond: the law's, with why."""
    Q = rows(0.5, 1.0)
    law_plan = plan_motion(LAW, Q0, Q, VLIM)
    plan, note = plan_demand(LAW, Q0, Q, VLIM, timing=Timing([0.0, 0.0]))
    assert note == '' and plan.duration == pytest.approx(law_plan.duration)
    plan, note = plan_demand(LAW, Q0, Q, VLIM, timing=Timing([3.0, 6.0]))
    assert note == 'as given' and plan.duration == pytest.approx(6.0)
    plan, note = plan_demand(LAW, Q0, Q, VLIM, timing=Timing([0.3, 0.6]))
    assert note.startswith('time-optimal through the points: the given timing breaks')
    assert plan.duration == pytest.approx(law_plan.duration)


def test_malformed_timing_is_invalid_input():
    """Decreasing or non-finite times, rows that do not match: InvalidInputError."""
    with pytest.raises(InvalidInputError, match='non-decreasing'):
        Timing([2.0, 1.0])
    with pytest.raises(InvalidInputError, match='finite'):
        Timing([1.0, float('nan')])
    with pytest.raises(InvalidInputError, match='one row per point'):
        Timing([1.0, 2.0], np.zeros((3, N)))
    with pytest.raises(InvalidInputError, match='accelerations need velocities'):
        Timing([1.0], None, np.zeros((1, N)))
    with pytest.raises(InvalidInputError, match='waypoints'):
        timed_plan(Q0, rows(0.5, 1.0), Timing([1.0]), VLIM, A_MAX)


def run_core(core, timing, Q, until, dt=0.01):
    """Drive ``core`` (an arm that follows its commands) from rest; return (t, q) per tick."""
    q, t, log = np.zeros(N), 0.0, []
    send_states(core, t, q)
    core.tick(t)
    send_demand(core, t, Q, timing=timing)
    while t < until:
        send_states(core, t, q)
        out = core.tick(t)
        log.append((t, q.copy(), core.status().values))
        q = q + out.qd * dt
        t = round(t + dt, 9)
    return log


def test_core_follows_the_timing_and_says_so():
    """The controller core: each point near its time (closed loop), the status says 'as given'."""
    from mover6_control.control.controller_core import ControllerCore
    from mover6_control.kinematics.arm import mover6
    core = ControllerCore(mover6())
    Q = rows(0.2, 0.4)
    log = run_core(core, Timing([2.0, 4.0]), Q, 6.0)
    assert log[-1][2]['timing'] == 'as given' and log[-1][2]['result'] == 'arrived'
    at = {round(t, 2): q for t, q, _ in log}
    assert np.abs(at[2.0] - Q[0]).max() < 0.01       # one tick of feedforward lag at most
    assert np.abs(at[1.0] - Q[0]).max() > 0.05       # not there early (time-optimal would be)
    assert np.abs(at[3.5] - Q[1]).max() > 0.005      # nor at the end
    assert np.abs(at[4.0] - Q[1]).max() < 0.002      # there at its time, within tolerance


def test_core_falls_back_to_time_optimal_and_says_why():
    """Timing beyond a_max: the law's time-optimal plan, its reason in the status."""
    from mover6_control.control.controller_core import ControllerCore
    from mover6_control.kinematics.arm import mover6
    core = ControllerCore(mover6())
    Q = rows(0.2, 0.4)
    log = run_core(core, Timing([0.3, 0.5]), Q, 4.0)
    note = log[-1][2]['timing']
    assert note.startswith('time-optimal through the points: the given timing breaks the limits')
    assert 'joint 1' in note and log[-1][2]['result'] == 'arrived'
    assert core.plan is None or core.plan.duration == pytest.approx(
        plan_motion(LAW, Q0, Q, mover6().velocity_limits).duration)


def test_action_goal_timing_mapped_by_name():
    """A goal's times, velocities and accelerations in the arm's joint order; mixes refused."""
    pytest.importorskip('control_msgs.action')
    from mover6_control.nodes.controller.trajectory_goal import map_timing, Result
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    names = [f'joint{i}' for i in range(1, 7)]
    trajectory = JointTrajectory(joint_names=names[::-1])
    for k in range(2):
        point = JointTrajectoryPoint(positions=[0.0] * N, velocities=[0.1 * k, 0, 0, 0, 0, 0.2],
                                     accelerations=[0.0] * N)
        point.time_from_start.sec, point.time_from_start.nanosec = k + 1, 500_000_000
        trajectory.points.append(point)
    timing = map_timing(trajectory, names)
    np.testing.assert_allclose(timing.times, [1.5, 2.5])
    np.testing.assert_allclose(timing.velocities[1], [0.2, 0, 0, 0, 0, 0.1])
    assert timing.accelerations.shape == (2, N) and timing.timed
    trajectory.points[0].velocities = []
    with pytest.raises(ValueError) as err:
        map_timing(trajectory, names)
    assert err.value.args[0] == Result.INVALID_GOAL and 'some points' in err.value.args[1]
    trajectory.points[0].velocities = [0.0] * N
    trajectory.points[1].accelerations = [float('nan')] * N
    with pytest.raises(ValueError) as err:
        map_timing(trajectory, names)
    assert err.value.args[0] == Result.INVALID_GOAL and 'finite' in err.value.args[1]


@pytest.mark.parametrize('extra', ['none', 'velocities', 'accelerations'])
def test_positions_at_many_times_are_the_samples_bit_for_bit(extra):
    # The collision guard samples a timed plan with MotionPlan.positions: one spline call for
    # the segment's times, exactly what sample(t) gives at each, after the end included.
    Q = rows(0.3, 0.6)
    V = np.array([[0.2, 0.1, 0, 0, 0, 0], [0.0] * N])
    A = np.array([[0.05, 0.0, 0, 0, 0, 0], [0.0] * N])
    timing = Timing([1.5, 3.0], *{'none': (), 'velocities': (V,), 'accelerations': (V, A)}[extra])
    plan = timed_plan(Q0, Q, timing, VLIM, A_MAX)
    times = np.concatenate([np.arange(0.0, plan.duration, 0.007),
                            [plan.duration, plan.duration + 1.0]])
    expected = np.array([plan.sample(t)[0] for t in times])
    assert np.array_equal(plan.positions(times), expected)
