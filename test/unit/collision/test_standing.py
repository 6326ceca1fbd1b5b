"""The collision parameters against where the arm stands (``collision.standing``), ROS-free."""

from mover6_control.collision.checker import CollisionSettings
from mover6_control.collision.geometry import ToolVolume
from mover6_control.collision.standing import StandingCheck
from mover6_control.errors import error_code, InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.parameters import SIM_BRIDGE
import numpy as np
import pytest

ARM = mover6()
HOME = np.asarray(SIM_BRIDGE['initial_q'].default)
WALL = (-0.5, 0.052, 0.14, 0.5, 0.5, 1.0)          # 52 mm beside the arm, +y
FRONT = (0.25, -0.5, 0.0, 0.5, 0.5, 1.0)           # the forearm's end at home is in it
TURNED = np.array([-np.pi / 2, 0.0, 0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope='module')
def standing():
    """Return the check with the start configuration known."""
    return StandingCheck(ARM, [HOME])


def test_a_wall_the_arm_stands_in_is_refused_with_the_link_and_depth(standing):
    """At start (no states): the start configuration; the reason names the plate and its mm."""
    with pytest.raises(InvalidInputError) as refused:
        standing.check(CollisionSettings(keep_out=WALL))
    assert error_code(refused.value) == 'in_collision'
    assert str(refused.value).startswith(
        'keep_out_boxes puts the arm in collision at the start configuration (no joint states '
        'yet): link2 plate is 46.3 mm inside keep-out box 0')


def test_where_it_stands_counts_and_bad_positions_fall_back_to_the_start(standing):
    """The front box: refused at home, taken turned away; NaN positions: the start again."""
    settings = CollisionSettings(keep_out=FRONT)
    with pytest.raises(InvalidInputError, match='where the arm stands: link'):
        standing.check(settings, HOME)
    standing.check(settings, TURNED)
    with pytest.raises(InvalidInputError, match='at the start configuration'):
        standing.check(settings, np.full(6, np.nan))


def test_a_set_no_deeper_than_the_settings_in_force_is_taken(standing):
    """The arm in a box in force: the box shrunk is taken, grown deeper is refused."""
    in_force = CollisionSettings(keep_out=(0.25, -0.5, 0.0, 0.5, 0.5, 1.0))
    standing.check(in_force, HOME, in_force)                        # unchanged: taken
    standing.check(CollisionSettings(keep_out=(0.3, -0.5, 0.0, 0.5, 0.5, 1.0)), HOME, in_force)
    with pytest.raises(InvalidInputError, match='keep_out_boxes'):
        standing.check(CollisionSettings(keep_out=(0.2, -0.5, 0.0, 0.5, 0.5, 1.0)), HOME,
                       in_force)
    standing.check(CollisionSettings(enabled=False, keep_out=WALL), HOME, in_force)


def test_a_table_margin_and_a_tool_the_arm_stands_in_are_refused_by_name(standing):
    """The margin above the turntable; a tool long enough to reach the table: by their names."""
    with pytest.raises(InvalidInputError, match=r'^table_margin .*link1 turntable is 69.0 mm'):
        standing.check(CollisionSettings(table_margin=0.2), HOME)
    bent = np.array([0.0, 0.0, 0.0, 0.0, 1.5, 0.0])                 # the wrist bent 86 deg
    standing.check(CollisionSettings(), bent)                        # the default tool clears
    long_tool = CollisionSettings(tool=ToolVolume('box', (0.06, 0.06, 0.4)))
    with pytest.raises(InvalidInputError,
                       match=r'^tool_shape/tool_size .*: link6 tool is [\d.]+ mm into the table'):
        standing.check(long_tool, bent)
