"""A program planned whole before it moves: IK, collision, blends, timing, the tool's speed."""

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, fk_batch, jacobian_batch
from mover6_control.programs.limits import JointLimits
from mover6_control.programs.program_error import ProgramError
from mover6_control.programs.program_file import load_program
from mover6_control.programs.program_plan import Action, Motion, plan_program, PlanSettings
import numpy as np
from program_examples import pick_and_place, POINTS, write_program
import pytest

ARM = mover6()
HOME = np.zeros(6)
LIMITS = JointLimits.of(ARM)
SETTINGS = PlanSettings()


def planned(tmp_path, text, q_start=HOME):
    return plan_program(ARM, load_program(ARM, write_program(tmp_path, text)), q_start)


def samples(motion: Motion, dt: float = 0.005):
    t = np.arange(0.0, motion.duration + dt, dt)
    q, qd, qdd = motion.trajectory.sample(np.minimum(t, motion.duration))
    return t, q, qd, qdd


def tool_speed(q, qd):
    return np.linalg.norm(np.einsum('mij,mj->mi', jacobian_batch(ARM, q)[:, :3], qd), axis=1)


def distance_from_segment(p, a, b):
    u = (b - a) / np.linalg.norm(b - a)
    s = np.clip((p - a) @ u, 0.0, np.linalg.norm(b - a))
    return np.linalg.norm(p - (a + s[:, None] * u), axis=1)


def test_the_pick_and_place_is_planned_whole_within_the_joint_limits(tmp_path):
    plan = planned(tmp_path, pick_and_place(repeat=3))
    # ptp; then per pass lin down, lin up + ptp across + lin down (blended), lin up
    assert [m.indices for m in plan.motions()][:4] == [(0,), (1,), (2, 3, 4), (5,)]
    assert len(plan.motions()) == 1 + 3 * 3
    assert plan.q_start.tolist() == HOME.tolist()
    np.testing.assert_allclose(plan.q_end, POINTS['above_place'], atol=1e-9)
    for motion in plan.motions():
        _, q, qd, qdd = samples(motion)
        assert ARM.within_limits(q.max(axis=0)) and ARM.within_limits(q.min(axis=0))
        assert np.all(np.abs(qd) <= LIMITS.velocity * (1 + 1e-3))
        assert np.all(np.abs(qdd) <= LIMITS.acceleration * (1 + 1e-2))
        np.testing.assert_allclose(qd[0], 0.0, atol=1e-9)      # rest to rest
        np.testing.assert_allclose(qd[-1], 0.0, atol=1e-9)
        np.testing.assert_allclose(q[-1], motion.moves[-1].q[-1], atol=1e-9)


def test_a_lin_runs_on_its_line_at_no_more_than_its_tool_speed(tmp_path):
    plan = planned(tmp_path, pick_and_place(repeat=1))
    lin = plan.motions()[1]                    # lin pick at 0.05 m/s from above_pick
    assert lin.moves[0].step.kind == 'lin' and lin.moves[0].step.speed == 0.05
    _, q, qd, _ = samples(lin)
    a, b = fk(ARM, np.array(POINTS['above_pick']))[:3, 3], fk(ARM, np.array(POINTS['pick']))[:3, 3]
    p = fk_batch(ARM, q)[:, :3, 3]
    assert distance_from_segment(p, a, b).max() < 1e-3          # [m]
    speed = tool_speed(q, qd)
    assert speed.max() <= 0.05 * (1 + 1e-3)
    assert speed.max() >= 0.05 * 0.9             # and it gets there: 7 cm at 0.5 m/s^2
    # the orientation is kept along the line (tool pointing down)
    z = fk_batch(ARM, q)[:, :3, 2]
    assert np.degrees(np.arccos(np.clip(z @ z[0], -1, 1))).max() < 0.5


def test_a_blend_passes_its_corners_within_the_radius_without_stopping(tmp_path):
    radius = 0.02
    plan = planned(tmp_path, pick_and_place(repeat=1, blend=radius))
    motion = plan.motions()[2]                  # lin up, ptp across, lin down: one motion
    assert motion.indices == (2, 3, 4) and len(motion.corners) == 2
    _, q, qd, _ = samples(motion)
    p = fk_batch(ARM, q)[:, :3, 3]
    speed = np.linalg.norm(qd, axis=1)
    inner = slice(int(0.05 * len(q)), int(0.95 * len(q)))
    assert speed[inner].min() > 1e-2               # no stop between the ends [rad/s]
    for corner in motion.corners:
        d = np.linalg.norm(p - corner.point, axis=1)
        assert d.min() <= corner.radius + SETTINGS.zone_tolerance
        assert d.min() > 1e-3                       # it rounds the corner, not through it
    # the lin up keeps its tool speed until its zone begins
    a = fk(ARM, np.array(POINTS['pick']))[:3, 3]
    corner = motion.corners[0].point
    on_line = np.linalg.norm(p - corner, axis=1) > radius
    up = on_line & (np.arange(len(p)) < np.argmin(np.linalg.norm(p - corner, axis=1)))
    assert distance_from_segment(p[up], a, corner).max() < 1e-3
    assert tool_speed(q[up], qd[up]).max() <= 0.05 * (1 + 1e-3)


def test_blending_shortens_the_cycle(tmp_path):
    blended = planned(tmp_path, pick_and_place(repeat=1, blend=0.02)).motion_time
    stopped = planned(tmp_path, pick_and_place(repeat=1, blend=0.0)).motion_time
    assert blended < stopped - 0.2, (blended, stopped)


def test_a_move_without_a_blend_stops_exactly_at_its_point(tmp_path):
    plan = planned(tmp_path, pick_and_place(repeat=1, blend=0.0))
    for motion in plan.motions():
        assert motion.corners == () and len(motion.moves) == 1
        q, qd, _ = motion.trajectory.sample(motion.duration)
        target = motion.moves[0].step.target
        np.testing.assert_allclose(fk(ARM, q)[:3, 3], target.position, atol=1e-6)
        np.testing.assert_allclose(qd, 0.0, atol=1e-9)


def test_a_speed_fraction_slows_the_moves_after_it_on_the_same_path(tmp_path):
    full = planned(tmp_path, 'steps:\n  - ptp: above_pick\n')
    half = planned(tmp_path, 'steps:\n  - speed: 0.5\n  - ptp: above_pick\n')
    assert isinstance(half.items[0], Action)
    a, b = full.motions()[0], half.motions()[0]
    assert b.fraction == 0.5
    # joint speeds times 0.5, accelerations times 0.25: the same path in twice the time
    assert b.duration == pytest.approx(2.0 * a.duration, rel=1e-2)
    np.testing.assert_allclose(b.q, a.q)


def test_an_unreachable_step_refuses_the_whole_program_with_its_line(tmp_path):
    text = ('steps:\n  - ptp: above_pick\n  - lin: pick\n'
            '  - lin: {pose: [0.9, 0.0, 0.3, 0, 1.5708, 0]}\n  - ptp: place\n')
    with pytest.raises(ProgramError) as info:
        planned(tmp_path, text)
    err = info.value
    assert (err.line, err.step) == (4, 2)
    assert err.code in ('out_of_reach', 'unreachable', 'reachable'), err
    assert 'step 3 "lin pose [0.9 0 0.3 0 1.5708 0]" cannot run' in str(err)


def test_a_step_into_the_table_is_refused_for_its_collision(tmp_path):
    low = dict(POINTS, pick=[0.4, 0.6, 0.7, 0.0, 0.6, 0.0])     # the tool 63 mm into the table
    path = write_program(tmp_path, 'steps:\n  - ptp: above_pick\n  - lin: pick\n', points=low)
    with pytest.raises(ProgramError) as info:
        plan_program(ARM, load_program(ARM, path), HOME)
    assert (info.value.line, info.value.code) == (3, 'collision')


def test_a_start_outside_the_limits_is_refused(tmp_path):
    program = load_program(ARM, write_program(tmp_path, 'steps:\n  - ptp: pick\n'))
    with pytest.raises(ProgramError) as info:
        plan_program(ARM, program, np.array([3.0, 0, 0, 0, 0, 0]))
    assert info.value.code == 'joint_limits' and 'joint1' in info.value.reason
