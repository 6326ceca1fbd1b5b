"""
One source of truth per parameter: ``mover6_control.parameters`` against everything else.

The tables must agree with the core (allowed values, the Mover6's encoder ticks, the defaults of
the settings dataclasses), with ``config/<node>.yaml`` and with the README's Parameters table;
``check_value`` must refuse what a node must refuse.
"""

import dataclasses
import math
import os
import re

from mover6_control.collision.checker import CollisionSettings
from mover6_control.collision.geometry import ToolVolume
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.profiles import (LawConfig, PROFILE_FAMILIES, STOP_AT_EACH_PROFILES,
                                             THROUGH_ALL_PROFILES)
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6, MOVER6_DRIVER_CYCLE, MOVER6_TICK_SIZE
from mover6_control.parameters import (check_value, CONTROLLER, JOG_UNITS, LIMIT_SETS, NODES,
                                       ParameterSpec, PATH_MOTIONS, PLANNER, POSE_MOTIONS,
                                       PROFILES, SIM_BRIDGE, SIM_MODES, TOOL_SHAPES)
from mover6_control.planning.planner_core import PlannerSettings
import pytest
from sim_bridge.model import ModelOptions
from sim_bridge.simulator import SimConfig
from source_tree import ROOT
import yaml


# (dataclass, field, table, parameter): each dataclass default that a parameter sets.
DATACLASS_DEFAULTS = (
    [(LawConfig, name, CONTROLLER, name)
     for name in ('profile', 'lambda_max', 't_max', 't_blend', 'a_max', 'j_max')]
    + [(ControllerConfig, name, CONTROLLER, name)
       for name in ('goal_tolerance', 'state_timeout', 'position_gain', 'settle_timeout',
                    'path_tolerance', 'rate', 'jog_units', 'speed_override',
                    'driver_tick_size', 'driver_cycle')]
    + [(PlannerSettings, name, PLANNER, name)
       for name in ('n_waypoints', 'max_step', 'max_angle_step', 'peak_height',
                    'max_joint_step', 'max_condition', 'position_tolerance',
                    'orientation_tolerance')]
    + [(SimConfig, name, SIM_BRIDGE, name)
       for name in ('mode', 'command_timeout', 'speed_override')]
    + [(ModelOptions, name, SIM_BRIDGE, name) for name in ('physics_dt', 'kv', 'damping')]
    + [(cls, name, table, param) for table in (PLANNER, CONTROLLER)
       for cls, name, param in ((CollisionSettings, 'enabled', 'collision_check'),
                                (CollisionSettings, 'table_margin', 'table_margin'),
                                (CollisionSettings, 'keep_out', 'keep_out_boxes'),
                                (CollisionSettings, 'max_joint_step', 'collision_step'),
                                (ToolVolume, 'shape', 'tool_shape'),
                                (ToolVolume, 'size', 'tool_size'))]
)


def default_of(cls, name):
    """Return the default of dataclass field ``name`` of ``cls``."""
    field = {f.name: f for f in dataclasses.fields(cls)}[name]
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return field.default


@pytest.mark.parametrize('cls,name,table,param', DATACLASS_DEFAULTS,
                         ids=lambda v: getattr(v, '__name__', str(v)))
def test_dataclass_defaults_are_the_node_defaults(cls, name, table, param):
    """Each core setting a parameter sets defaults to the parameter's default."""
    value = default_of(cls, name)
    if isinstance(value, tuple):
        value = tuple(value)
    assert value == table[param].default, f'{cls.__name__}.{name}'


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


@pytest.mark.parametrize('node', sorted(NODES))
def test_config_file_matches_the_table(node):
    """config/<node>.yaml: every parameter, no other key, each valid and the default."""
    with open(os.path.join(ROOT, 'config', f'{node}.yaml')) as f:
        values = yaml.safe_load(f)[f'/**/{node}']['ros__parameters']
    table = NODES[node]
    assert list(values) == list(table), 'same parameters, in the same order'
    for name, value in values.items():
        check_value(table[name], value)
        default = table[name].default
        assert (tuple(value) if isinstance(value, list) else value) == default, name


def yaml_comments(path):
    """
    Return {parameter: its comment} of a parameter file.

    A parameter's comment is the one on its line, the comment lines indented under it that
    follow it (and a comment on a continued value's line), and the comment lines right above it.
    """
    out, above, current = {}, [], None
    with open(path) as f:
        lines = f.read().splitlines()
    for line in lines:
        entry = re.match(r'^    (\w+):\s*(?:[^#]*?)(?:\s+#\s?(.*))?$', line)
        comment = re.match(r'^(\s*)#\s?(.*)$', line)
        if entry:
            current = entry.group(1)
            out[current] = ' '.join(above + [entry.group(2) or ''])
            above = []
        elif comment and current and len(comment.group(1)) > 4:
            out[current] += ' ' + comment.group(2)
        elif comment:
            above.append(comment.group(2))
            current = None
        elif line.strip() and current and '#' in line:
            out[current] += ' ' + line.split('#', 1)[1]
        else:
            above = []
    return out


@pytest.mark.parametrize('node', sorted(NODES))
def test_config_file_comments_agree_with_the_table(node):
    """
    config/<node>.yaml's comments: each parameter's unit in brackets and every allowed value.

    The table is the source (``parameters``); a file's comments may say more, never otherwise.
    """
    comments = yaml_comments(os.path.join(ROOT, 'config', f'{node}.yaml'))
    units = {spec.unit for table in NODES.values() for spec in table.values()} - {''}
    assert set(comments) == set(NODES[node])
    for name, spec in NODES[node].items():
        text = comments[name]
        assert text.strip(), f'{name} has no comment'
        if spec.unit:
            assert f'[{spec.unit}]' in text, f'{name}: unit [{spec.unit}] missing: {text}'
        else:
            wrong = [unit for unit in units if f'[{unit}]' in text]
            assert not wrong, f'{name} has no unit, its comment says {wrong}: {text}'
        missing = [value for value in spec.allowed if not re.search(rf'\b{value}\b', text)]
        assert not missing, f'{name}: the comment does not name {missing}: {text}'


def readme_parameters_section():
    """Return the README's '## Parameters' section."""
    with open(os.path.join(ROOT, 'README.md')) as f:
        text = f.read()
    match = re.search(r'^## Parameters\n(.*?)(?=^## )', text, re.M | re.S)
    assert match, 'README has no Parameters section'
    return match.group(1)


@pytest.mark.parametrize('node', sorted(NODES))
def test_readme_lists_every_parameter(node):
    """Every parameter of the node appears in a row of its node in the README's table."""
    rows = [line for line in readme_parameters_section().splitlines()
            if line.startswith(f'| {node} |')]
    names = set()
    for row in rows:
        names.update(re.findall(r'`(\w+)`', row.split('|')[2]))
    assert names == set(NODES[node]), f'missing {set(NODES[node]) - names}, ' \
                                      f'unknown {names - set(NODES[node])}'


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
