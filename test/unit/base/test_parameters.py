"""
One source of truth per parameter: ``mover6_control.parameters`` against everything else.

The tables must agree with the core (allowed values, the Mover6's encoder ticks; the settings
dataclasses take their defaults from them); ``check_value`` must refuse what a node must
refuse. The parameter files and docs/parameters.md are made from the tables
(test/lint/test_generated_files.py).
"""

import math

from mover6_control.collision.geometry import ToolVolume
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.profiles import (LawConfig, PROFILE_FAMILIES, STOP_AT_EACH_PROFILES,
                                             THROUGH_ALL_PROFILES)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6, MOVER6_DRIVER_CYCLE, MOVER6_TICK_SIZE
from mover6_control.parameters import (check_value, CONTROLLER, JOG_UNITS, LIMIT_SETS, NODES,
                                       ParameterSpec, PATH_MOTIONS, PLANNER, POSE_MOTIONS,
                                       PROFILES, SIM_BRIDGE, SIM_MODES, TOOL_SHAPES)
import pytest
from sim_bridge.simulator import SimConfig


def test_the_law_defaults_to_what_the_node_runs():
    """The disagreement that started this: the law defaults to continuous, as the node does."""
    assert LawConfig().profile == 'continuous' == CONTROLLER['profile'].default
    assert ControllerConfig().law.profile == 'continuous'


def test_allowed_values_are_the_core_names():
    """The allowed strings are the tables the core takes its names from, and it takes each."""
    assert PLANNER['motion'].allowed == POSE_MOTIONS
    assert PLANNER['path_motion'].allowed == PATH_MOTIONS
    assert CONTROLLER['profile'].allowed == PROFILES
    assert CONTROLLER['jog_units'].allowed == JOG_UNITS
    assert SIM_BRIDGE['mode'].allowed == SIM_MODES
    for table in NODES.values():
        if 'limit_set' in table:        # the nodes with an arm model's limits
            assert table['limit_set'].allowed == LIMIT_SETS
            assert table['limit_set'].read_only
    assert {n for n, t in NODES.items() if 'limit_set' not in t} == {
        'state_publisher', 'markers', 'recorder'}
    for table in (PLANNER, CONTROLLER):
        assert table['tool_shape'].allowed == TOOL_SHAPES
    # Each name has its meaning in the core (the core imports these tables from parameters).
    for profile in PROFILES:
        assert LawConfig(profile=profile).profile == profile
    assert set(PROFILES) == ({'synchronised', 'trapezoidal', 'jerk_limited', 'continuous'}
                             | set(STOP_AT_EACH_PROFILES) | set(THROUGH_ALL_PROFILES))
    assert sorted(sum(PROFILE_FAMILIES.values(), ())) == sorted(PROFILES)
    for limit_set in LIMIT_SETS:
        assert mover6(limit_set).n_joints == 6
    for units in JOG_UNITS:
        assert ControllerConfig(jog_units=units).jog_units == units
    for shape in TOOL_SHAPES:
        assert ToolVolume(shape).shape == shape
    for mode in SIM_MODES:
        assert SimConfig(mode=mode).mode == mode
    for refused in (lambda: LawConfig(profile='banana'), lambda: mover6('banana'),
                    lambda: ControllerConfig(jog_units='banana'), lambda: ToolVolume('banana'),
                    lambda: SimConfig(mode='banana')):
        with pytest.raises(InvalidInputError, match='banana'):
            refused()


def test_mover6_driver_constants_are_the_arms():
    """The controller's driver defaults are the Mover6's ticks and cycle from the arm model."""
    assert CONTROLLER['driver_tick_size'].default == MOVER6_TICK_SIZE
    assert CONTROLLER['driver_cycle'].default == MOVER6_DRIVER_CYCLE


def test_descriptions_use_words_a_user_knows():
    """Every parameter is described, with no internal words."""
    for table in NODES.values():
        for spec in table.values():
            assert spec.description
            assert 'seed' not in spec.description.lower(), spec.name


@pytest.mark.parametrize('spec,value,words', [
    (CONTROLLER['rate'], -5.0, 'from 1 to 1000 Hz'),
    (CONTROLLER['rate'], 100, 'type float'),
    (CONTROLLER['rate'], math.nan, 'finite'),
    (PLANNER['motion'], 'banana', 'one of: linear, parabolic, joint'),
    (PLANNER['n_waypoints'], 1, 'from 2 to 10000'),
    (PLANNER['n_waypoints'], 20.0, 'type int'),
    (PLANNER['n_waypoints'], True, 'type int'),
    (SIM_BRIDGE['publish_clock'], 1, 'type bool'),
    (SIM_BRIDGE['initial_q'], [0.0, 4.0], 'each value from'),
    (SIM_BRIDGE['initial_q'], [0, 0], 'type float_list'),
    (SIM_BRIDGE['initial_q'], [], 'type float_list'),
    (CONTROLLER['driver_tick_size'], [0.001] * 5 + [-0.001], 'each value from'),
    (CONTROLLER['driver_tick_size'], [0.001], 'exactly 6 values'),
    (CONTROLLER['driver_tick_size'], [0.001] * 1000, 'exactly 6 values, got 1000'),
    (CONTROLLER['tool_size'], [0.05] * 7, 'exactly 3 values'),
    (PLANNER['tool_size'], [0.05], 'exactly 3 values'),
    (PLANNER['keep_out_boxes'], [0.0] * 5, 'a multiple of 6'),
])
def test_check_value_refuses_with_a_reason(spec, value, words):
    """A bad value is refused, and the reason names the parameter and what is allowed."""
    with pytest.raises(InvalidInputError) as err:
        check_value(spec, value)
    assert spec.name in str(err.value)
    assert words in str(err.value)


def test_a_refusal_quotes_a_long_value_by_its_length():
    """A 1,000-value list is refused with its first values and its length, not all of them."""
    with pytest.raises(InvalidInputError) as err:
        check_value(CONTROLLER['keep_out_boxes'], [9.0] * 1002)
    assert '(1002 values)' in str(err.value) and len(str(err.value)) < 300


def test_check_value_takes_valid_values():
    """Values at the ends of the range and allowed names pass."""
    check_value(CONTROLLER['rate'], 1.0)
    check_value(CONTROLLER['rate'], 1000.0)
    check_value(PLANNER['motion'], 'parabolic')
    check_value(SIM_BRIDGE['initial_q'], [0.0, -1.0, 1.0])
    check_value(PLANNER['frame_id'], 'world')


def test_a_spec_refuses_a_bad_default():
    """The table cannot declare a default its own check would refuse."""
    with pytest.raises(InvalidInputError, match='one of'):
        ParameterSpec('x', 'str', 'c', '', 'text', allowed=('a', 'b'))
    with pytest.raises(InvalidInputError, match='from 0 to 1'):
        ParameterSpec('x', 'float', 2.0, '', 'text', 0.0, 1.0)
    with pytest.raises(InvalidInputError, match='type'):
        ParameterSpec('x', 'complex', 2.0, '', 'text')
