"""
The first-run calibration file: written, read back, and checked against the joint file.

The real joint file (config/mover6_joints.yaml) and files written with ``write_calibration``.
"""

from dataclasses import replace

from mover6_control.errors import InvalidInputError
from mover6_control.hardware.calibration import (
    calibration_refusal, check_calibration, JointCalibration, load_calibration,
    write_calibration)
from mover6_control.hardware.scaling import load_joints
import pytest

_, JOINTS = load_joints()


def confirmed():
    """Return every joint confirmed with the gear it has."""
    return {j.name: JointCalibration(j.gear, True, True, 100, 5.0) for j in JOINTS}


def test_written_and_read_back(tmp_path):
    path = str(tmp_path / 'cal.yaml')
    write_calibration(path, confirmed(), '2026-12-05T01:00:00Z', '/x/mover6_joints.yaml')
    assert load_calibration(path) == confirmed()
    assert check_calibration(load_calibration(path), JOINTS) == ([], [])
    warnings = []
    assert calibration_refusal(path, JOINTS, warnings.append) == '' and warnings == []


def test_a_direction_seen_wrong_refuses_until_the_sign_is_fixed(tmp_path):
    cal = confirmed()
    cal['joint1'] = replace(cal['joint1'], sign_confirmed=False)
    errors, _ = check_calibration(cal, JOINTS)
    assert len(errors) == 1 and 'joint1' in errors[0] and 'flip the sign' in errors[0]
    flipped = [replace(j, gear=-j.gear) if j.name == 'joint1' else j for j in JOINTS]
    errors, warnings = check_calibration(cal, flipped)       # fixed: run the check again
    assert errors == [] and any('run first_run again' in w for w in warnings)
    errors, _ = check_calibration(confirmed(), flipped)       # a confirmed sign flipped since
    assert len(errors) == 1 and 'changed sign' in errors[0]
    path = str(tmp_path / 'cal.yaml')
    write_calibration(path, cal, 'now', 'x')
    assert 'flip the sign' in calibration_refusal(path, JOINTS, lambda text: None)


def test_warnings_for_what_was_not_checked(tmp_path):
    cal = confirmed()
    del cal['joint6']
    cal['joint5'] = replace(cal['joint5'], scale_confirmed=False)
    cal['joint4'] = replace(cal['joint4'], gear=cal['joint4'].gear * 1.12)
    errors, warnings = check_calibration(cal, JOINTS)
    assert errors == []
    assert [w.split(':')[0] for w in warnings] == ['joint4', 'joint5', 'joint6']
    said = []
    assert calibration_refusal('', JOINTS, said.append) == '' and 'first_run' in said[0]


@pytest.mark.parametrize('text, reason', [
    ('joints: {joint1: {sign_confirmed: true}}', 'gear'),
    ('joints: {joint1: {gear: 528.2, sign_confirmed: 1}}', 'true, false or null'),
    ('joints: {joint1: {gear: .nan}}', 'finite'),
    ('nothing: here', 'mapping "joints"'),
    ('[', 'cannot be read')])
def test_a_bad_file_is_refused_with_the_reason(tmp_path, text, reason):
    path = tmp_path / 'cal.yaml'
    path.write_text(text)
    with pytest.raises(InvalidInputError, match=reason):
        load_calibration(str(path))
    assert reason in calibration_refusal(str(path), JOINTS, lambda text: None)
    assert 'cannot be read' in calibration_refusal(str(tmp_path / 'none.yaml'), JOINTS, print)
