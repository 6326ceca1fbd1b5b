"""Point and program files: what loads, and each bad input refused with its file, line, code."""

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.programs.limits import CartesianLimits
from mover6_control.programs.points import load_points, Point, PointBook
from mover6_control.programs.program_error import PROGRAM_CODES, ProgramError
from mover6_control.programs.program_file import load_program
from mover6_control.programs.steps import GripperStep, Move, SpeedStep, WaitStep
import numpy as np
from program_examples import pick_and_place, POINTS, write_program
import pytest

ARM = mover6()
LIMITS = CartesianLimits.load()


def refusal(tmp_path, text, has_gripper=True, points=POINTS, in_points=False) -> ProgramError:
    path = write_program(tmp_path, text, points=points)
    with pytest.raises(ProgramError) as info:
        load_program(ARM, path, has_gripper=has_gripper)
    err = info.value
    where = str(tmp_path / 'points.yaml') if in_points else path
    assert err.path == where and str(err).startswith(f'{where}:')
    return err


def test_the_pick_and_place_program_loads_with_its_points_and_run_order(tmp_path):
    path = write_program(tmp_path, pick_and_place(repeat=3, gripper=True))
    program = load_program(ARM, path)
    assert program.name == 'pick_and_place'
    assert program.points.names() == list(POINTS)
    # 1 ptp + 3 passes of 7 steps (4 lin, 1 ptp, 2 gripper)
    assert len(program.run) == 1 + 3 * 7
    assert [r.index for r in program.run] == list(range(22))
    assert [r.passes for r in program.run[1:8]] == [(1,)] * 7
    assert program.run[-1].passes == (3,)
    lin = program.run[1].step
    assert isinstance(lin, Move) and lin.kind == 'lin' and lin.speed == 0.05
    assert lin.rot_speed == LIMITS.max_rot_vel          # the default: Pilz's limit
    assert lin.line == 7
    assert isinstance(program.run[2].step, GripperStep) and program.run[2].step.action == 'close'
    np.testing.assert_allclose(lin.target.T, fk(ARM, np.array(POINTS['pick'])))


def test_every_step_kind_loads(tmp_path):
    path = write_program(tmp_path, """\
        steps:
          - speed: 0.5
          - ptp: {pose: [0.28, 0.1, 0.25, 0, 1.5708, 0]}
          - circ: place
            via: above_pick
            speed: 0.08
            rot_speed: 0.4
          - wait: 0.25
          - wait: {input: 2, state: low, timeout: 5}
        """)
    run = [r.step for r in load_program(ARM, path).run]
    assert isinstance(run[0], SpeedStep) and run[0].fraction == 0.5
    assert run[1].kind == 'ptp' and run[1].target.joints is None
    np.testing.assert_allclose(run[1].target.position, [0.28, 0.1, 0.25], atol=1e-12)
    assert run[2].kind == 'circ' and run[2].via.label == 'above_pick'
    assert (run[2].speed, run[2].rot_speed) == (0.08, 0.4)
    assert isinstance(run[3], WaitStep) and run[3].seconds == 0.25
    assert (run[4].channel, run[4].state, run[4].timeout) == (2, 'low', 5.0)


@pytest.mark.parametrize('text, line, code', [
    # a typo in a key of a step
    ('steps:\n  - ptp: above_pick\n  - lin: pick\n    sped: 0.05\n', 4, 'unknown_key'),
    # a typo in a step's kind
    ('steps:\n  - ptpp: above_pick\n', 2, 'unknown_key'),
    # a typo at the top level
    ('step:\n  - ptp: above_pick\n', 1, 'unknown_key'),
    # an unknown point
    ('steps:\n  - ptp: above_pick\n  - lin: pik\n', 3, 'unknown_point'),
    ('steps:\n  - circ: place\n    via: nowhere\n', 3, 'unknown_point'),
    # a speed above the limits: Pilz's Cartesian tool speed, a fraction above 1
    ('steps:\n  - lin: pick\n    speed: 0.5\n', 3, 'speed_limit'),
    ('steps:\n  - lin: pick\n    rot_speed: 5.0\n', 3, 'speed_limit'),
    ('steps:\n  - speed: 1.5\n', 2, 'speed_limit'),
    # a blend radius larger than half of a neighbouring segment (pick is 7 cm below above_pick)
    ('steps:\n  - ptp: above_pick\n  - lin: pick\n    blend: 0.04\n  - lin: above_pick\n',
     3, 'blend_radius'),
    # a blend with no move after it
    ('steps:\n  - lin: pick\n    blend: 0.01\n  - wait: 1\n', 2, 'blend_radius'),
    ('steps:\n  - lin: pick\n    blend: 0.01\n', 2, 'blend_radius'),
    # values of the wrong type or range
    ('steps:\n  - lin: pick\n    speed: fast\n', 3, 'bad_value'),
    ('steps:\n  - lin: pick\n    speed: -0.1\n', 3, 'bad_value'),
    ('steps:\n  - wait: {input: 9}\n', 2, 'bad_value'),
    ('steps:\n  - repeat: 0\n    steps: [{ptp: pick}]\n', 2, 'bad_value'),
    ('steps:\n  - ptp: {pose: [0.3, 0, 0.2]}\n', 2, 'bad_value'),
    ('steps:\n  - gripper: half\n', 2, 'bad_value'),
    # missing keys
    ('steps:\n  - circ: place\n', 2, 'missing'),
    ('steps:\n  - repeat: 2\n', 2, 'missing'),
    ('program: x\n', 1, 'missing'),
    # no YAML, and YAML that is no program
    ('steps:\n  - ptp: [above_pick\n', 3, 'syntax'),
    ('steps:\n  - ptp: a\n  - ptp: b\n    ptp: c\n', 4, 'syntax'),
    ('- ptp: above_pick\n', 1, 'syntax'),
    ('steps: []\n', 1, 'syntax'),
])
def test_a_bad_program_is_refused_with_its_line_and_code(tmp_path, text, line, code):
    err = refusal(tmp_path, text)
    assert (err.line, err.code) == (line, code), str(err)
    assert code in PROGRAM_CODES
    assert str(err).startswith(f'{err.path}:{line}: ')


def test_a_gripper_step_on_a_stack_without_a_gripper_is_refused(tmp_path):
    err = refusal(tmp_path, pick_and_place(gripper=True), has_gripper=False)
    assert err.code == 'no_gripper' and err.line == 9
    write_program(tmp_path, pick_and_place(gripper=False))
    assert load_program(ARM, str(tmp_path / 'program.yaml'), has_gripper=False).run


def test_a_bad_points_file_is_refused_with_its_line(tmp_path):
    outside = dict(POINTS, pick=[0.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    err = refusal(tmp_path, 'steps:\n  - ptp: pick\n', points=outside, in_points=True)
    assert err.code == 'bad_value'
    assert err.line == 5 and 'joint limits' in err.reason
    short = dict(POINTS, pick=[0.0, 0.0])
    err = refusal(tmp_path, 'steps:\n  - ptp: pick\n', points=short, in_points=True)
    assert err.code == 'bad_value'


def test_a_point_name_must_be_a_name():
    with pytest.raises(ProgramError) as info:
        Point.of(ARM, '2nd point', np.zeros(6))
    assert info.value.code == 'bad_value'


def test_points_are_taught_renamed_deleted_and_read_back(tmp_path):
    path = str(tmp_path / 'points.yaml')
    book = PointBook(path)
    q = np.array([0.1, 0.2, 0.3, 0.0, 0.4, 0.0])
    book = book.taught(Point.of(ARM, 'a', q)).taught(Point.of(ARM, 'b', np.zeros(6)))
    with pytest.raises(ProgramError) as info:
        book.taught(Point.of(ARM, 'a', np.zeros(6)))
    assert info.value.code == 'duplicate'
    book = book.renamed('a', 'first').deleted('b')
    with pytest.raises(ProgramError) as info:
        book.deleted('b')
    assert info.value.code == 'unknown_point'
    book.save()
    again = load_points(ARM, path)
    assert again.names() == ['first']
    np.testing.assert_allclose(again.get('first').q, q, atol=1e-6)
    # the pose is the tool's (FK), written for reading: X Y Z of the flange
    np.testing.assert_allclose(again.get('first').pose[:3], fk(ARM, q)[:3, 3], atol=1e-6)


def test_an_edited_pose_changes_nothing(tmp_path):
    path = tmp_path / 'points.yaml'
    path.write_text('points:\n  a:\n    joints: [0, 0, 0, 0, 0, 0]\n'
                    '    pose: [9, 9, 9, 0, 0, 0]\n')
    point = load_points(ARM, str(path)).get('a')
    np.testing.assert_allclose(point.pose, [0.345, 0.0, 0.4425, 0.0, 0.0, 0.0], atol=1e-6)
