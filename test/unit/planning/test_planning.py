"""
Planning from the current configuration to a goal (ROS-free): shapes, singular starts.

Examples of each shape first; then every shape from any start, the singular home included: the
planner refuses no feasible pair. A pair (start configuration, goal pose) counts as feasible for
a shape when its Cartesian path, sampled every 1 mm (and 1 mrad) and solved by closed form with
branch tracking, is continuous and inside the joint limits. From a wrist-singular start such as
home (q5 = 0) the first step may turn q4 against q6 in place (the self-motion there), so the
tracking may begin on any branch of the first waypoint that this turn reaches.
"""

from hypothesis import assume, given, HealthCheck, settings
from hypothesis import strategies as st
from mover6_control.collision.checker import CollisionSettings
from mover6_control.errors import InvalidInputError, UnreachableError
from mover6_control.kinematics.arm import LIMIT_SETS, mover6
from mover6_control.kinematics.forward import (condition_number, fk, fk_batch, jacobian,
                                               jacobian_batch)
from mover6_control.kinematics.ik_closed_form import ik_closed_form_batch
from mover6_control.kinematics.path_ik import solve_path
from mover6_control.kinematics.rotations import pose_error, pose_from_xyzabc
from mover6_control.motion import paths
from mover6_control.motion.metrics import max_deviation_from_polyline
from mover6_control.planning.planner_core import plan_path_goal, plan_pose_goal, PlannerSettings
from mover6_control.tools.goal_convention import pose_from_goal
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

ARMS = {name: mover6(name) for name in LIMIT_SETS}
ARM = ARMS['within_90_deg']
HOME = np.zeros(6)
GOAL = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
SETTINGS = PlannerSettings()
# The shapes from any start:
DENSE = {'max_step': 0.001, 'max_angle_step': 0.001}
# Largest joint change [rad] between 1 mm samples of a continuous path: a branch switch or a
# pass by a singularity shows as a far larger one.
DENSE_JUMP = 0.05
PEAK = 0.04        # [m] parabolic peak height of the property test
# Feasible here is kinematic (the random starts include poses in the table): the collision
# check, which refuses such pairs for the table with reason 'collision', is off; its own tests
# are test_collision.py.
SHAPE_SETTINGS = PlannerSettings(peak_height=PEAK, collision=CollisionSettings(enabled=False))
SHAPES = ('linear', 'parabolic', 'spline', 'arc', 'joint')


def check_plan(plan, q_start, T_goal, settings=SETTINGS):
    """Assert the invariants every plan keeps."""
    Q = plan.q
    assert Q.shape[1] == 6 and Q.shape[0] >= 2
    assert np.allclose(Q[0], q_start)
    assert all(ARM.within_limits(q) for q in Q)
    assert np.abs(np.diff(Q, axis=0)).max() <= settings.max_joint_step + 1e-12
    pos, rot = pose_error(fk(ARM, Q[-1]), T_goal)
    assert pos <= settings.position_tolerance and rot <= settings.orientation_tolerance


def test_linear_from_singular_home_inserts_a_wrist_turn_that_stays_on_the_line():
    """Home (q5 = 0) is singular: the plan turns the wrist in place first, then follows."""
    plan = plan_pose_goal(ARM, HOME, GOAL, 'linear')
    check_plan(plan, HOME, GOAL)
    assert plan.n_waypoints > SETTINGS.n_waypoints   # the wrist turn was inserted
    # FK of a fine joint-space interpolation of the waypoints stays on the straight line.
    fine = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a)
                           for a, b in zip(plan.q[:-1], plan.q[1:])])
    line = np.stack([fk(ARM, HOME)[:3, 3], GOAL[:3, 3]])
    assert max_deviation_from_polyline(fk_batch(ARM, fine)[:, :3, 3], line) < 1e-3


@pytest.mark.parametrize('n', [3, 5, 50])
def test_wrist_turn_is_made_in_place_for_any_sampling(n):
    """However coarse the path, the turn out of the singular home keeps the tool still."""
    settings = PlannerSettings(n_waypoints=n)
    plan = plan_pose_goal(ARM, HOME, GOAL, 'linear', settings)
    check_plan(plan, HOME, GOAL, settings)
    turn = plan.q[:plan.n_waypoints - n + 1]
    for T in fk_batch(ARM, turn):
        pos, rot = pose_error(T, fk(ARM, HOME))
        assert pos < 1e-9 and rot < 1e-9


def test_linear_from_a_regular_pose_needs_no_wrist_turn():
    """Away from singularities the plan is exactly the sampled path."""
    q0 = plan_pose_goal(ARM, HOME, GOAL, 'linear').q[-1]
    goal = pose_from_xyzabc(0.30, -0.05, 0.33, 0.0, np.pi / 2, 0.0)
    plan = plan_pose_goal(ARM, q0, goal, 'linear')
    check_plan(plan, q0, goal)
    assert plan.n_waypoints == SETTINGS.n_waypoints


@pytest.mark.parametrize('motion', ['parabolic', 'joint'])
def test_other_pose_motions_reach_the_goal(motion):
    """Parabolic and joint moves end at the goal within tolerance."""
    q0 = plan_pose_goal(ARM, HOME, GOAL, 'linear').q[-1]
    goal = pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0)
    plan = plan_pose_goal(ARM, q0, goal, motion)
    check_plan(plan, q0, goal)
    if motion == 'parabolic':
        mid = plan.poses[len(plan.poses) // 2][:3, 3]
        straight_mid = (fk(ARM, q0)[:3, 3] + goal[:3, 3]) / 2
        assert mid[2] > straight_mid[2] + 0.5 * SETTINGS.peak_height


def test_spline_and_arc_through_via_poses():
    """Path goals pass through their via pose."""
    via = pose_from_xyzabc(0.33, -0.02, 0.38, 0.0, np.pi / 2, 0.0)
    goal = pose_from_xyzabc(0.28, 0.10, 0.36, 0.0, np.pi / 2, 0.0)
    for motion in ('spline', 'arc'):
        plan = plan_path_goal(ARM, HOME, via[None], goal, motion)
        check_plan(plan, HOME, goal)
        d = np.linalg.norm(fk_batch(ARM, plan.q)[:, :3, 3] - via[:3, 3], axis=1).min()
        assert d < 0.01, f'{motion} passes {d * 1e3:.1f} mm from the via pose'


def test_goal_at_the_current_pose_is_a_hold():
    """A goal equal to the current pose plans a two-row hold, not an error."""
    plan = plan_pose_goal(ARM, HOME, fk(ARM, HOME), 'linear')
    assert plan.q.shape == (2, 6) and np.allclose(plan.q, HOME)


def test_unreachable_goal_and_bad_input_raise_with_reasons():
    """Refusals carry a reason; bad input is an InvalidInputError."""
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, HOME, pose_from_xyzabc(0.9, 0.0, 0.4, 0.0, np.pi / 2, 0.0))
    assert err.value.reason == 'out_of_reach'
    with pytest.raises(InvalidInputError):
        plan_pose_goal(ARM, HOME, GOAL, 'zigzag')
    with pytest.raises(InvalidInputError):
        plan_pose_goal(ARM, [0.0, np.nan, 0, 0, 0, 0], GOAL)
    with pytest.raises(InvalidInputError):
        plan_path_goal(ARM, HOME, np.stack([GOAL, GOAL]), GOAL, 'arc')
    with pytest.raises(InvalidInputError):
        PlannerSettings(n_waypoints=1)


def test_a_path_refusal_says_a_joint_move_gets_to_the_goal():
    """From the report's IK example, the README's next line is refused on the way; joint: fine."""
    q_ik = plan_pose_goal(ARM, HOME, pose_from_goal(ARM, 0.1, 0.1, 0.2, 0.0, np.pi / 2, 0.0),
                          'linear').q[-1]
    goal = pose_from_goal(ARM, 0.30, 0.05, 0.36, 0.0, 0.0, 0.0)
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, q_ik, goal, 'linear')
    assert err.value.reason in ('discontinuity', 'joint_limits')
    assert 'the goal itself is reachable inside the limits: a joint move' in str(err.value)
    plan = plan_pose_goal(ARM, q_ik, goal, 'joint')
    position, _ = pose_error(fk(ARM, plan.q[-1]), goal)
    assert position < 1e-6


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
    T = paths.linear_curve(T_start, T_goal, n=3).poses[1]
    T[:3, 3] += offset
    return T


def shape_path(shape, T_start, T_goal, via, **sampling):
    """Return the Cartesian path of a shape (joint moves: the straight line)."""
    if shape == 'parabolic':
        return paths.parabolic_curve(T_start, T_goal, PEAK, **sampling).poses
    if shape == 'spline':
        return paths.spline_curve(T_start, via[None], T_goal, **sampling).poses
    if shape == 'arc':
        return paths.arc_curve(T_start, via, T_goal, **sampling).poses
    return paths.linear_curve(T_start, T_goal, **sampling).poses


def regular_pose(arm, T, settings):
    """
    Return True when a solution of ``T`` inside the limits is away from singularities.

    The planner refuses goal and via poses reachable only with a Jacobian condition number
    above ``max_condition``; such pairs are not feasible.
    """
    Q, ok = ik_closed_form_batch(arm, T[None], within_limits=True)
    return any(condition_number(arm, q) <= settings.max_condition for q in Q[0][ok[0]])


def refusals(arm, q_start, T_goal, via, settings=SHAPE_SETTINGS):
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
    plan = plan_path_goal(arm, pair[0], pair[2][None], pair[1], 'arc', SHAPE_SETTINGS)
    assert plan.n_waypoints > SHAPE_SETTINGS.n_waypoints        # waypoints were inserted
    assert np.abs(np.diff(plan.q, axis=0)).max() <= SHAPE_SETTINGS.max_joint_step
    positions = paths.arc_curve(fk(arm, pair[0]), pair[2], pair[1], **DENSE).poses[:, :3, 3]
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
    dense = paths.linear_curve(curve.poses[0], curve.poses[-1], **DENSE).poses
    assert not dense_continuous(arm, dense, q_a)
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
    poses = paths.parabolic_curve(T_home, goal, 0.04, **DENSE).poses
    assert not dense_continuous(ARM, poses, HOME)
    with pytest.raises(UnreachableError) as err:
        plan_pose_goal(ARM, HOME, goal, 'parabolic', PlannerSettings(peak_height=0.04))
    assert err.value.reason == 'joint_limits' and 'joint4' in str(err.value)
    # The straight line and a lower parabola are fine from home.
    assert dense_continuous(ARM, paths.parabolic_curve(T_home, goal, 0.02, **DENSE).poses, HOME)
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
    poses = paths.parabolic_curve(fk(arm, HOME), goal, 0.04, **DENSE).poses
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
        plan_path_goal(ARM, HOME, vias, near, shape, SHAPE_SETTINGS)
