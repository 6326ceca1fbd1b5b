"""
The collision checker and the planner's and controller's use of it (issue 14).

ROS-free: the checker, the planner core, the controller core and the simulator are driven
directly. The shapes are the simulator's own (one geometry), so the last tests compare the
checker with MuJoCo's contacts in the simulator.
"""

import re

from core_testing import send_demand, send_states
from mover6_control.collision.checker import CollisionChecker, CollisionSettings, densify
from mover6_control.collision.geometry import (build_geometry, keep_out_boxes, ToolVolume)
from mover6_control.control.collision_guard import CollisionGuard, plan_samples
from mover6_control.control.controller_core import ControllerCore
from mover6_control.errors import InvalidInputError, REASONS, UnreachableError
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.kinematics.ik_closed_form import ik_closed_form
from mover6_control.planning.planner_core import (collision_refusal, plan_path_goal,
                                                  plan_pose_goal, PlannerSettings)
import numpy as np
import pytest
from readme_goals import goal_argv, plan_readme_goal, readme_goal_lines
from sim_bridge.simulator import Simulator

ARM = mover6('within_90_deg')
HOME = np.zeros(6)
CHECKER = CollisionChecker(ARM)
# Rotating the home orientation (tool along +x) by +90 deg about base y points the tool down.
DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
# Two configurations, each clear of everything, whose straight joint-space
# motion sweeps the tool through the base (found by a seeded search; within +-90 deg the base
# can hardly be reached without the table).
THROUGH_BASE = np.array([[-0.53, 0.5, 1.08, -1.23, 1.45, -1.16],
                         [-0.13, 0.43, 1.07, 1.21, 1.4, -0.49]])
# Upper arm tilted forward, forearm folded down onto the shoulder.
SELF_COLLIDING = np.array([0.0, 1.5, 1.5, 0.0, 0.0, 0.0])


def table_goal():
    """Return the goal of the issue: flange pointing down at x=0.25 y=0 z=0 of base_link."""
    T = fk(ARM, HOME)
    T[:3, :3] = DOWN @ T[:3, :3]
    T[:3, 3] = (0.25, 0.0, 0.0)
    return T


def test_home_is_free_with_clearances():
    """Home touches nothing; the clearances are reported for each kind."""
    check = CHECKER.check_configurations(HOME[None])
    assert check.free
    assert check.clearance['table'] > 0.05 and check.clearance['self'] > 0.01


def test_the_table_surface_goal_collides_with_the_table():
    """Every configuration that reaches the goal puts the tool into the table."""
    solutions = ik_closed_form(ARM, table_goal(), within_limits=True)
    assert len(solutions) > 0
    for q in solutions:
        check = CHECKER.check_configurations(q[None])
        assert not check.free
        assert check.first.shapes == ('link6 tool', 'table')
        # The 80 mm tool points straight down from the flange at z = 0, plus the 20 mm margin.
        assert check.first.depth == pytest.approx(0.10, abs=2e-3)


def test_the_planner_refuses_the_table_goal_for_the_table():
    """The planner refuses it with the 'collision' reason, naming the tool and the table."""
    for motion in ('linear', 'joint'):
        with pytest.raises(UnreachableError) as err:
            plan_pose_goal(ARM, HOME, table_goal(), motion)
        assert err.value.reason == 'collision'
        assert 'link6 tool is 100 mm into the table margin' in str(err.value)
    assert 'collision' in REASONS


def test_the_check_can_be_switched_off():
    """With the check off, the checker calls everything free (the planner's switch)."""
    off = CollisionChecker(ARM, CollisionSettings(enabled=False))
    assert off.check_path(np.stack([HOME, SELF_COLLIDING])).free


def test_a_path_through_the_base_collides_although_both_ends_are_clear():
    """The waypoints are clear; the swept motion between them is not, and is refused."""
    ends = CHECKER.check_configurations(THROUGH_BASE)
    assert ends.free and min(ends.clearance.values()) > 0.0
    check = CHECKER.check_path(THROUGH_BASE)
    assert not check.free
    assert check.first.shapes[0] == 'link6 tool' and check.first.shapes[1].startswith('base ')
    assert 0.0 < check.first.fraction < 1.0 and check.first.waypoint == 0
    err = collision_refusal(CHECKER, THROUGH_BASE)
    assert err.reason == 'collision'
    assert re.search(r'link6 tool and base \w+ overlap by \d+ mm \(self-collision\) at \d+ % of '
                     r'the path', str(err)), str(err)


def test_a_keep_out_box_refuses_a_path_through_it_and_nothing_else():
    """A box in front of the arm stops a straight move through it, not one beside it."""
    box = (0.30, -0.05, 0.26, 0.40, 0.05, 0.36)     # below the wrist at home (z 0.40 and up)
    boxed = CollisionChecker(ARM, CollisionSettings(keep_out=box))
    up = np.array([0.0, -0.6, 0.0, 0.0, 0.0, 0.0])      # lean back: the wrist rises, clear
    down = np.array([0.0, 0.3, 0.6, 0.0, 0.0, 0.0])     # forearm tilted down through the box
    assert CHECKER.check_path(np.stack([HOME, down])).free
    check = boxed.check_path(np.stack([up, down]))
    assert not check.free
    assert check.first.kind == 'keep_out' and check.first.shapes[1] == 'keep-out box 0'
    assert 'inside keep-out box 0' in boxed.message(check)
    # The same box leaves every other motion alone: home, and a turn to the side.
    assert boxed.check_path(np.stack([HOME, [1.2, 0.0, 0.0, 0.0, 0.0, 0.0]])).free
    assert boxed.check_path(np.stack([up, [0.0, -0.6, -0.5, 0.0, 0.0, 0.0]])).free


def test_keep_out_boxes_parse_six_values_each_and_skip_empty_ones():
    """The flat parameter list: 6 values per box; a box without volume is none."""
    assert keep_out_boxes((0.0,) * 6) == ()
    boxes = keep_out_boxes((0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, -1, -1, 0, 0, 0, 1))
    assert [b.name for b in boxes] == ['keep-out box 0', 'keep-out box 2']
    with pytest.raises(InvalidInputError):
        keep_out_boxes((0.0,) * 5)


def test_a_self_colliding_configuration_is_found():
    """Forearm folded onto the shoulder: links two or more apart overlap; neighbours never."""
    check = CHECKER.check_configurations(SELF_COLLIDING[None])
    assert not check.free and check.first.kind == 'self'
    assert {name.split()[0] for name in check.first.shapes} == {'link4', 'base'}
    names = [s.name for s in CHECKER.geometry.shapes]
    bodies = {s.name: s.body for s in CHECKER.geometry.shapes}
    assert abs(bodies[check.first.shapes[0]] - bodies[check.first.shapes[1]]) >= 2
    assert all(abs(CHECKER.geometry.shapes[i].body - CHECKER.geometry.shapes[j].body) >= 2
               for i, j in CHECKER.geometry.self_pairs()), names


def test_the_elbow_folds_to_the_vendors_limit_without_touching():
    """The vendor's joint-3 limit (1.31 rad) is where the real arm stops, untouched."""
    q = np.array([0.0, 0.0, 1.309, 0.0, 0.0, 0.0])
    assert CHECKER.check_configurations(q[None]).clearance['self'] > 0.0


def test_a_box_tool_is_checked_too():
    """A box tool pointing into the table is found, and the default capsule tool's size."""
    boxed = CollisionChecker(ARM, CollisionSettings(tool=ToolVolume('box', (0.1, 0.04, 0.12))))
    q = ik_closed_form(ARM, table_goal(), within_limits=True)[0]
    check = boxed.check_configurations(q[None])
    assert check.first.shapes == ('link6 tool', 'table')
    assert check.first.depth == pytest.approx(0.14, abs=2e-3)
    none = CollisionChecker(ARM, CollisionSettings(tool=ToolVolume('none')))
    assert none.geometry.tool is None
    with pytest.raises(InvalidInputError):
        ToolVolume('sphere')


def test_dense_samples_keep_to_the_joint_step():
    """No joint moves more than the step between samples; every waypoint is a sample."""
    W = np.array([HOME, [0.3, -0.2, 0.1, 0.0, 0.5, -1.0], [0.3, -0.2, 0.1, 0.0, 0.5, -1.0005]])
    Q, segment = densify(W, 0.01)
    assert np.abs(np.diff(Q, axis=0)).max() <= 0.01 + 1e-12
    for w in W:
        assert np.any(np.all(np.isclose(Q, w), axis=1))
    assert segment[0] == 0 and segment[-1] == 1


def _goals_from(text_lines):
    return [line for line in text_lines if goal_argv(line)[0] in ('pose', 'path')]


@pytest.mark.parametrize('line', _goals_from(readme_goal_lines()))
def test_every_readme_goal_is_free(line):
    """Each README goal plans from home with the check on, and its swept motion is free."""
    plan = plan_readme_goal(goal_argv(line))
    assert CHECKER.check_path(plan.q).free, line


def test_every_demo_goal_is_free_and_the_table_goal_refused():
    """The showcase, in order as the demo sends it: moves free, refusals for their reason."""
    from mover6_control.tools.demo import SHOWCASE
    from mover6_control.tools.goal_convention import poses_from_numbers
    q = HOME
    reasons = []
    for step in SHOWCASE:
        Ts = poses_from_numbers([v for p in step.poses for v in p], quat=False, arm=ARM)
        settings = PlannerSettings(peak_height=step.params.get('peak_height', 0.05))
        try:
            if step.kind == 'pose':
                plan = plan_pose_goal(ARM, q, Ts[-1], step.params['motion'], settings)
            else:
                plan = plan_path_goal(ARM, q, Ts[:-1], Ts[-1], step.params['path_motion'],
                                      settings)
        except UnreachableError as err:
            reasons.append(err.reason)
            assert err.reason == step.expect, (step.name, str(err))
            continue
        assert step.expect == 'arrived', step.name
        assert CHECKER.check_path(plan.q).free, step.name
        q = plan.q[-1]
    assert 'collision' in reasons


def test_the_controller_refuses_a_colliding_demand_with_the_reason():
    """A demand sent directly is checked as the law moves it; the table goal is refused."""
    core = ControllerCore(ARM)
    core.collision_guard = CollisionGuard(ARM)
    send_states(core, 0.0, HOME, np.zeros(6))
    core.tick(0.0)
    q_table = ik_closed_form(ARM, table_goal(), within_limits=True)[0]
    with pytest.raises(InvalidInputError, match='collision: link6 tool is .* into the table'):
        send_demand(core, 0.01, np.stack([HOME, q_table]), 'g1')
    assert core.status().values['rejected'].startswith('collision: link6 tool')
    # Both ends clear, the motion between them through the base: refused as well.
    send_states(core, 0.02, THROUGH_BASE[0], np.zeros(6))
    core.tick(0.02)
    with pytest.raises(InvalidInputError, match='collision: link6 tool and base'):
        send_demand(core, 0.03, THROUGH_BASE, 'g2')
    # A free demand is taken.
    send_states(core, 0.04, HOME, np.zeros(6))
    core.tick(0.04)
    assert send_demand(core, 0.05, np.array([[0.2, 0.1, -0.1, 0.0, 0.3, 0.0]]), 'g3') >= 1


def test_plan_samples_cover_the_whole_motion_within_the_step():
    """The law's reference is sampled from start to end, no joint step above the limit."""
    from mover6_control.control.planners import plan_motion
    from mover6_control.control.profiles import LawConfig
    W = np.array([[0.5, 0.2, -0.3, 0.4, 0.6, -0.8], [0.0, 0.1, 0.0, 0.0, 0.0, 0.0]])
    plan = plan_motion(LawConfig(), HOME, W, ARM.velocity_limits, np.zeros(6))
    Q = plan_samples(plan, 0.01)
    assert np.allclose(Q[0], HOME) and np.allclose(Q[-1], W[-1])
    assert np.abs(np.diff(Q, axis=0)).max() <= 0.01 + 1e-12


def test_the_simulator_has_the_checkers_shapes_and_agrees_on_contacts():
    """Same geoms in the simulation: a configuration collides there exactly when here."""
    geometry = build_geometry(ARM)
    sim = Simulator(ARM)
    names = set(sim._geom_names)
    for shape in geometry.shapes:
        assert shape.name.replace(' ', '_') in names
    plain = CollisionChecker(ARM, CollisionSettings(table_margin=0.0))
    rng = np.random.default_rng(11)
    hits = 0
    for q in rng.uniform(ARM.lower, ARM.upper, (150, 6)):
        sim.reset(q)
        touching = sim.contact_steps > 0
        free = plain.check_configurations(q[None]).free
        assert touching != free, (q, sim.contacts())
        hits += touching
    assert 10 < hits < 140


def test_an_arm_touching_something_can_be_moved_away_but_not_deeper():
    """From a pose in the table: home is allowed (escape), further down is not."""
    q_in = ik_closed_form(ARM, table_goal(), within_limits=True)[0]
    away = np.stack([q_in, HOME])
    assert not CHECKER.check_path(away).free
    assert CHECKER.check_path(away, escape=True).free
    assert collision_refusal(CHECKER, away) is None
    deeper = np.stack([q_in, q_in + np.array([0.0, 0.2, 0.0, 0.0, 0.0, 0.0])])
    check = CHECKER.check_path(deeper, escape=True)
    assert not check.free and check.first.shapes == ('link6 tool', 'table')
