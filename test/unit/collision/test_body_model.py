"""
The collision model holds the Mover6's own body: the maker's meshes against the checker.

ROS-free. The meshes are the shipped ones (``meshes/``), read as the derivation reads them; the
configurations are a seeded uniform sample within the arm's limits.
"""

import os

from mover6_control.collision import body_fit
from mover6_control.collision.checker import CollisionChecker, CollisionSettings
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk_frames
from mover6_control.planning.planner_core import plan_pose_goal
from mover6_control.resources import MESH_DIR
from mover6_control.tools.goal_convention import poses_from_numbers
import numpy as np
import pytest

ARM = mover6('within_90_deg')
CHECKER = CollisionChecker(ARM)
MESHES = {b: body_fit.load_vertices(os.path.join(MESH_DIR, name))[0]
          for b, name in enumerate(body_fit.MESH_FILES)}


def _frames(q):
    return [np.eye(4)] + list(fk_frames(ARM, q)[:6])


def outside_model(q, shapes=CHECKER.geometry.capsules):
    """Return the largest distance [m] of any mesh vertex outside every shape at ``q``."""
    T = _frames(q)
    points = np.concatenate([V @ T[b][:3, :3].T + T[b][:3, 3] for b, V in MESHES.items()])
    inside = np.full(len(points), np.inf)
    for s in shapes:
        R, p = T[s.body][:3, :3], T[s.body][:3, 3]
        kind = 'cylinder' if type(s).__name__ == 'Cylinder' else 'capsule'
        inside = np.minimum(inside, body_fit.signed_distance(
            kind, R @ np.asarray(s.p0) + p, R @ np.asarray(s.p1) + p, s.radius, points))
    return float(inside.max())


def test_every_mesh_vertex_is_inside_the_model_at_random_configurations():
    """At every sampled configuration each vertex is MARGIN inside the shapes (less 1 um)."""
    rng = np.random.default_rng(41)
    worst = max(outside_model(q) for q in rng.uniform(ARM.lower, ARM.upper, (200, 6)))
    assert worst <= -body_fit.MARGIN + 1e-6, worst


def test_a_keep_out_box_touching_any_real_housing_is_refused():
    """A 2 mm box around a random vertex of a random link's mesh is a collision, every time."""
    rng = np.random.default_rng(7)
    for q in rng.uniform(ARM.lower, ARM.upper, (40, 6)):
        body = int(rng.integers(1, 7))
        V = MESHES[body]
        T = _frames(q)[body]
        v = T[:3, :3] @ V[rng.integers(len(V))] + T[:3, 3]
        box = tuple(v - 0.001) + tuple(v + 0.001)
        check = CollisionChecker(ARM, CollisionSettings(keep_out=box)).check_configurations(
            q[None])
        assert not check.free and check.first.kind in ('keep_out', 'table', 'self'), (q, body)


def test_a_box_cutting_the_shoulder_is_refused_naming_link1():
    """Link1 is checked against the world: a box into the shoulder housing's end collides."""
    box = (0.035, -0.02, 0.136, 0.1, 0.02, 0.15)    # above the base, under link2's housing
    boxed = CollisionChecker(ARM, CollisionSettings(keep_out=box))
    check = boxed.check_configurations(np.zeros(6)[None])
    assert not check.free and check.first.shapes[1] == 'keep-out box 0'
    assert check.first.shapes[0].startswith('link1 '), check.first.shapes


@pytest.mark.parametrize('side', [1.0, -1.0])
def test_the_reports_linear_goal_past_a_wall_52_mm_beside_the_arm_is_refused(side):
    """
    The wall the real upper arm stands in: every sample of the linear goal collides, named.

    The arm at home is already in the wall (the real side plate reaches 0.052 m), so the whole
    motion collides with it; the goal is refused unless it moves the arm out (``escape``).
    """
    wall = (-0.5, 0.052, 0.14, 0.5, 0.5, 1.0) if side > 0 else (-0.5, -0.5, 0.14, 0.5, -0.052,
                                                                1.0)
    goal = poses_from_numbers([0.445, 0.0, 0.4425, 0.0, 0.0, 0.0], quat=False, arm=ARM)[-1]
    plan = plan_pose_goal(ARM, np.zeros(6), goal, 'linear')       # arrives without the wall
    walled = CollisionChecker(ARM, CollisionSettings(keep_out=wall))
    check = walled.check_path(plan.q)
    assert not check.free and check.first.kind == 'keep_out'
    assert check.first.shapes[0].split()[0] in ('link1', 'link2', 'link3'), check.first.shapes
    Q = plan.q
    assert all(not walled.check_configurations(q[None]).free for q in Q)
    assert 'inside keep-out box 0' in walled.message(check)


def test_the_minimum_table_margin_is_derived_from_the_meshes_and_is_the_parameters():
    """body_model's constant is the derivation's, and the table_margin minimum of both nodes."""
    from mover6_control.collision import body_model
    from mover6_control.parameters import BODY_MIN_TABLE_MARGIN, CONTROLLER, PLANNER
    shapes = [body_fit.FittedShape(*row) for row in body_model.BODY_SHAPES]
    outside = body_fit.largest_outside(MESH_DIR, shapes)
    assert body_fit.min_table_margin(outside) == body_model.MIN_TABLE_MARGIN
    assert BODY_MIN_TABLE_MARGIN == body_model.MIN_TABLE_MARGIN
    assert PLANNER['table_margin'].minimum == CONTROLLER['table_margin'].minimum \
        == BODY_MIN_TABLE_MARGIN


def test_at_the_minimum_table_margin_no_accepted_configuration_puts_a_vertex_below_the_table():
    """2,000 configurations within the widest limits: each one the checker takes stays above."""
    from mover6_control.collision.geometry import ToolVolume
    from mover6_control.parameters import BODY_MIN_TABLE_MARGIN, PLANNER
    from mover6_control.tools.derive_collision import widest_limits
    checker = CollisionChecker(ARM, CollisionSettings(
        tool=ToolVolume('none', PLANNER['tool_size'].default),
        table_margin=BODY_MIN_TABLE_MARGIN))
    shaft = body_fit.BODY_SLABS[1][1][0][0]     # link1's shaft turns inside the base's column
    body = {b: V[V[:, 2] >= shaft] if b == 1 else V for b, V in MESHES.items() if b > 0}
    rng = np.random.default_rng(4141)
    lowest, taken = np.inf, 0
    for q in rng.uniform(*widest_limits(), (2000, 6)):
        if checker.check_configurations(q[None]).clearance['table'] < 0.0:
            continue                     # refused for the table
        taken += 1
        T = _frames(q)
        lowest = min(lowest, min(float((V @ T[b][:3, :3].T + T[b][:3, 3])[:, 2].min())
                                 for b, V in body.items()))
    assert taken > 500, taken
    assert lowest >= BODY_MIN_TABLE_MARGIN + body_fit.MARGIN - 1e-6, lowest
