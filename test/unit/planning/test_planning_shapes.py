"""
Every shape from any start, the singular home included: the planner refuses no feasible pair.

A pair (start configuration, goal pose) counts as feasible for a shape when its Cartesian path,
sampled every 1 mm (and 1 mrad) and solved by closed form with branch tracking, is continuous
and inside the joint limits. From a wrist-singular start such as home (q5 = 0) the first step
may turn q4 against q6 in place (the self-motion there), so the tracking may begin on any
branch of the first waypoint that this turn reaches.
"""

from hypothesis import assume, given, HealthCheck, settings
from hypothesis import strategies as st
from mover6_control.collision.checker import CollisionSettings
from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.kinematics.arm import LIMIT_SETS, mover6
from mover6_control.kinematics.forward import condition_number, fk, jacobian, jacobian_batch
from mover6_control.kinematics.ik_closed_form import ik_closed_form_batch
from mover6_control.kinematics.path_ik import solve_path
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.motion import paths
from mover6_control.planning.planner_core import plan_path_goal, plan_pose_goal, PlannerSettings
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

ARMS = {name: mover6(name) for name in LIMIT_SETS}
ARM = ARMS['within_90_deg']
HOME = np.zeros(6)
DENSE = {'max_step': 0.001, 'max_angle_step': 0.001}
# Largest joint change [rad] between 1 mm samples of a continuous path: a branch switch or a
# pass by a singularity shows as a far larger one.
DENSE_JUMP = 0.05
PEAK = 0.04        # [m] parabolic peak height of the property test
# Feasible here is kinematic (the random starts include poses in the table): the collision
# check, which refuses such pairs for the table with reason 'collision', is off; its own tests
# are test_collision.py.
SETTINGS = PlannerSettings(peak_height=PEAK, collision=CollisionSettings(enabled=False))
SHAPES = ('linear', 'parabolic', 'spline', 'arc', 'joint')


def dense_continuous(arm, poses, q_start, jump=DENSE_JUMP, max_condition=None):
    """
    Return True when ``poses`` (dense) have a continuous in-limit joint path from ``q_start``.

    Closed form at every pose, then branch tracking (nearest branch, max-norm) from each branch
    of the first waypoint that ``q_start`` reaches: directly, or after a self-motion along the
    Jacobian's null space when ``q_start`` is singular. With ``max_condition`` the path must
    also not move towards a singularity beyond it (the planner's rule: a condition number above
    ``max_condition`` and rising), so leaving a singular start is allowed.
    """
    Q, ok = ik_closed_form_batch(arm, poses[1:], within_limits=True, q_ref=q_start)
    first = np.flatnonzero(ok[0])
    if condition_number(arm, q_start) > 1e6:
        v = np.linalg.svd(jacobian(arm, q_start))[2][-1]
        starts = [q_start + float(v @ (Q[0, b] - q_start)) * v for b in first]
    else:
        starts = [q_start] * len(first)
    for b, q0 in zip(first, starts):
        if np.abs(Q[0, b] - q0).max() > jump:
            continue
        track = [Q[0, b]]
        for k in range(1, len(Q)):
            cand = Q[k][ok[k]]
            if len(cand) == 0:
                break
            steps = np.abs(cand - track[-1]).max(axis=1)
            j = int(np.argmin(steps))
            if steps[j] > jump:
                break
            track.append(cand[j])
        else:
            if max_condition is None:
                return True
            sv = np.linalg.svd(jacobian_batch(arm, np.array(track)), compute_uv=False)
            with np.errstate(divide='ignore'):
                cond = np.where(sv[:, -1] > 0.0, sv[:, 0] / sv[:, -1], np.inf)
            before = np.concatenate([[condition_number(arm, q_start)], cond[:-1]])
            if not np.any((cond > max_condition) & (cond > before)):
                return True
    return False


def goal_near(T_start, move, turn):
    """Return ``T_start`` moved by ``move`` (3,) [m] and turned by rotation vector ``turn``."""
    T = np.array(T_start)
    T[:3, 3] += move
    T[:3, :3] = Rotation.from_rotvec(turn).as_matrix() @ T[:3, :3]
    return T


def via_near_line(T_start, T_goal, offset):
    """Return the mid pose of the straight line from start to goal, moved by ``offset`` [m]."""
    T = paths.linear_path(T_start, T_goal, n=3)[1]
    T[:3, 3] += offset
    return T


def shape_path(shape, T_start, T_goal, via, **sampling):
    """Return the Cartesian path of a shape (joint moves: the straight line)."""
    if shape == 'parabolic':
        return paths.parabolic_path(T_start, T_goal, PEAK, **sampling)
    if shape == 'spline':
        return paths.spline_path(T_start, via[None], T_goal, **sampling)
    if shape == 'arc':
        return paths.arc_path(T_start, via, T_goal, **sampling)
    return paths.linear_path(T_start, T_goal, **sampling)


def regular_pose(arm, T, settings):
    """
    Return True when a solution of ``T`` inside the limits is away from singularities.

    The planner refuses goal and via poses reachable only with a Jacobian condition number
    above ``max_condition``; such pairs are not feasible.
    """
    Q, ok = ik_closed_form_batch(arm, T[None], within_limits=True)
    return any(condition_number(arm, q) <= settings.max_condition for q in Q[0][ok[0]])


def refusals(arm, q_start, T_goal, via, settings=SETTINGS):
    """
    Return ({shape: refusal} for the feasible shapes, the feasible shapes) of one pair.

    A pair whose straight line is not feasible, or whose goal or via pose is near a singularity,
    has no feasible shape.
    """
    T_start = fk(arm, q_start)
    if not (regular_pose(arm, T_goal, settings) and regular_pose(arm, via, settings)):
        return {}, []
    feasible = []
    for shape in SHAPES:
        if shape == 'joint' or dense_continuous(
                arm, shape_path(shape, T_start, T_goal, via, **DENSE), q_start,
                max_condition=settings.max_condition):
            feasible.append(shape)
        elif shape == 'linear':
            return {}, []
    found = {}
    for shape in feasible:
        try:
            if shape in ('spline', 'arc'):
                plan_path_goal(arm, q_start, via[None], T_goal, shape, settings)
            else:
                plan_pose_goal(arm, q_start, T_goal, shape, settings)
        except UnreachableError as err:
            found[shape] = f'{err.reason}: {err}'
    return found, feasible


def regular_start(arm, values):
    """Return the configuration ``values`` when it is away from singularities, else None."""
    q = np.array(values)
    if abs(q[4]) < 0.3 or condition_number(arm, q) > 50.0:
        return None
    return q


def random_pair(arm, start, move, turn, offset):
    """
    Return (q_start, T_goal, via) from drawn numbers, or None for a start near a singularity.

    ``start`` is home (all zeros) or joint values; ``move``, ``turn`` and ``offset`` are vectors
    in the unit cube: the goal is 1.2 to 12 cm and up to 0.5 rad from the start pose, the via
    pose 2 mm to 1 cm off the middle of the straight line, across it.
    """
    q_start = HOME if not np.any(start) else regular_start(arm, start)
    # The via pose's offset across the line (an arc needs three points not on one line).
    across = offset - (offset @ move) / max(move @ move, 1e-12) * move
    if (q_start is None or np.linalg.norm(move) < 0.1 or np.linalg.norm(across) < 0.2):
        return None       # near a singularity, or too short a move or offset
    T_start = fk(arm, q_start)
    T_goal = goal_near(T_start, 0.12 * move / max(1.0, np.linalg.norm(move)),
                       0.5 * turn / max(1.0, np.linalg.norm(turn)))
    via = via_near_line(T_start, T_goal, 0.01 * across / max(1.0, np.linalg.norm(across)))
    return q_start, T_goal, via


vector = st.tuples(*[st.floats(-1.0, 1.0)] * 3).map(np.array)
joint = st.floats(-1.3, 1.3)


@pytest.mark.parametrize('limit_set', LIMIT_SETS)
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(start=st.one_of(st.just(tuple(HOME)), st.tuples(*[joint] * 6)),
       move=vector, turn=vector, offset=vector)
def test_no_shape_refuses_a_feasible_pair(limit_set, start, move, turn, offset):
    """Linear, parabolic, spline, arc and joint plans from home or a regular start."""
    arm = ARMS[limit_set]
    pair = random_pair(arm, start, move, turn, offset)
    assume(pair is not None)
    found, feasible = refusals(arm, *pair)
    assume(feasible)
    assert not found, f'refused feasible shapes from {pair[0]}: {found}'


def test_a_large_step_on_a_continuous_path_is_followed_not_refused():
    """
    A continuous path whose wrist turns fast between two waypoints plans, finer there.

    Next to the wrist singularity a continuous path can turn the wrist by more than
    max_joint_step between two of its 20 waypoints (hypothesis found these from q5 = 0.5:
    'waypoint 13 needs a jump of 0.374 rad in joint4'). The planner follows the path's own
    curve there and inserts the waypoints it finds: every step within the limit, every row on
    the path.
    """
    arm = ARMS['hardware']
    pair = random_pair(arm, (0.0, 0.0, 0.0, 0.0, 0.5, 0.0), np.array([0.0, 0.0, -0.5]),
                       np.array([1.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    found, feasible = refusals(arm, *pair)
    assert feasible == list(SHAPES) and not found, found
    plan = plan_path_goal(arm, pair[0], pair[2][None], pair[1], 'arc', SETTINGS)
    assert plan.n_waypoints > SETTINGS.n_waypoints        # waypoints were inserted
    assert np.abs(np.diff(plan.q, axis=0)).max() <= SETTINGS.max_joint_step
    positions = paths.arc_path(fk(arm, pair[0]), pair[2], pair[1], **DENSE)[:, :3, 3]
    for T in plan.poses:
        assert np.linalg.norm(positions - T[:3, 3], axis=1).min() < 1e-3
    for q, T in zip(plan.q, plan.poses):
        assert np.abs(fk(arm, q) - T).max() < 1e-6


@pytest.mark.parametrize('d4', (0.3, 0.6, 1.0))
def test_a_wrist_flip_is_still_refused_when_followed_finely(d4):
    """
    A real branch flip is refused even when the path is followed finely.

    A straight line that passes beside the wrist singularity flips q4 and q6 by nearly pi
    within a millimetre: followed finely, the jump stays, and it is refused.
    """
    arm = ARMS['hardware']
    q_a = np.array([0.0, 0.3, 0.0, 0.2, 0.3, 0.1])
    q_b = np.array([0.0, 0.3, 0.0, 0.2 + d4, -0.3, 0.1])
    curve = paths.linear_curve(fk(arm, q_a), fk(arm, q_b), n=20)
    assert not dense_continuous(arm, paths.linear_path(curve.poses[0], curve.poses[-1], **DENSE),
                                q_a)
    with pytest.raises(UnreachableError) as err:
        solve_path(arm, curve.poses[1:], q_a, pose_between=lambda k, s: curve.between(k + 1, s))
    assert err.value.reason == 'discontinuity'
    assert err.value.details['joint_step'] > 1.0


def test_readme_parabolic_from_home_within_90_deg():
    """
    The README's former parabolic goal (peak 0.04 m) from home: joint 4 would pass +90 deg.

    (The README now shows it with a 0.02 m peak.)

    The parabola rises before it falls; with the goal's orientation the wrist's q4 goes
    1.22 -> 1.51 rad on the first fifth and continues past pi / 2 (the other wrist branch,
    q4 - pi, is below -pi / 2 there). No in-limit joint path follows it, so the refusal is
    right and says that the joint limit is the cause.
    """
    goal = pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0)
    T_home = fk(ARM, HOME)
    poses = paths.parabolic_path(T_home, goal, 0.04, **DENSE)
    assert not dense_continuous(ARM, poses, HOME)
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, HOME, goal, 'parabolic', PlannerSettings(peak_height=0.04))
    assert err.value.reason == 'joint_limits' and 'joint4' in str(err.value)
    # The straight line and a lower parabola are fine from home.
    assert dense_continuous(ARM, paths.parabolic_path(T_home, goal, 0.02, **DENSE), HOME)
    for motion, peak in (('linear', 0.04), ('parabolic', 0.02)):
        plan_pose_goal(ARM, HOME, goal, motion, PlannerSettings(peak_height=peak))


def test_readme_parabolic_from_home_hardware_limits():
    """
    With the hardware limits the README's parabola is feasible from home.

    It is so on the wrist branch q4 < 0: the turn out of the singular home must pick that
    branch, not the one nearest home (q4 > 0, which leaves the limits of q6 on the way).
    """
    arm = mover6('hardware')
    goal = pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0)
    poses = paths.parabolic_path(fk(arm, HOME), goal, 0.04, **DENSE)
    assert dense_continuous(arm, poses, HOME)
    plan = plan_pose_goal(arm, HOME, goal, 'parabolic', PlannerSettings(peak_height=0.04))
    assert plan.q[:, 3].max() <= 1e-9     # q4 turns negative and stays there
    assert all(arm.within_limits(q) for q in plan.q)


@pytest.mark.parametrize('shape', ('arc', 'parabolic', 'spline'))
def test_a_path_goal_is_refused_for_its_via_count_before_any_via_is_solved(shape):
    """
    Issue 24 (6): the cheap check first: the count, before each via pose's reachability.

    The first via pose is out of reach: it was refused for that after checking it (and all the
    others: 10,000 vias took half a minute), now for the count, before any is solved.
    """
    far = pose_from_xyzabc(1.0, 0.0, 0.4, 0.0, np.pi / 2, 0.0)
    near = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
    vias = np.stack([far] + [near] * (2 if shape != 'spline' else 200))
    words = ('at most 100 via poses, got 201' if shape == 'spline'
             else f'{shape} needs exactly one via pose, got 3')
    with pytest.raises(InvalidInputError, match=words):
        plan_path_goal(ARM, HOME, vias, near, shape, SETTINGS)
