"""The stack both launchers start (``mover6_control.stack``): its options and its plan."""

import shlex

from mover6_control import stack
from mover6_control.parameters import CONTROLLER, JOG_UNITS, LIMIT_SETS, NODES, PROFILES
import pytest


def test_the_controllers_choices_and_defaults():
    for name, allowed in (('profile', PROFILES), ('jog_units', JOG_UNITS),
                          ('limit_set', LIMIT_SETS)):
        option = stack.OPTION[name]
        assert option.default == CONTROLLER[name].default == option.choices[0]
        assert sorted(option.choices) == sorted(allowed)


def test_a_value_not_among_the_choices_is_refused():
    with pytest.raises(ValueError, match='--profile must be one of: continuous'):
        stack.plan({'profile': 'banana'})
    with pytest.raises(ValueError, match='unknown option'):
        stack.plan({'speed': 'fast'})


def test_the_simulator():
    plan = stack.plan({})
    assert [s.name for s in plan] == ['sim_bridge', 'controller', 'planner', 'state_publisher',
                                      'markers']
    by_name = {s.name: s for s in plan}
    assert by_name['sim_bridge'].parameters == {'limit_set': 'within_90_deg',
                                                'mode': 'rad_per_s'}
    assert by_name['controller'].parameters['state_timeout'] == \
        CONTROLLER['state_timeout'].default
    assert by_name['controller'].parameters['cycle_driver'] is False
    assert by_name['markers'].parameters == {'frame_prefix': ''}
    # Every parameter a start sets is a parameter of that node, and valid for it.
    for start in stack.plan({'jog_units': 'fraction_of_max', 'namespace': '/arm2'}):
        for name, value in start.parameters.items():
            assert name in NODES[start.name], (start.name, name)
    sim = {s.name: s for s in stack.plan({'jog_units': 'fraction_of_max'})}['sim_bridge']
    assert sim.parameters['mode'] == 'vendor_driver'


def test_no_sim_and_the_hardware_choices():
    assert 'sim_bridge' not in {s.name for s in stack.plan({'sim': 'false'})}
    can = {s.name: s for s in stack.plan({'hardware': 'can', 'can_interface': 'socketcan'})}
    assert 'sim_bridge' not in can and 'can_sim' not in can
    driver = can['driver'].parameters
    assert (driver['can_interface'], driver['can_channel'], driver['enable_on_start']) == \
        ('socketcan', '/dev/ttyUSB0', False)
    assert can['controller'].parameters['state_timeout'] == 0.5
    assert can['controller'].parameters['cycle_driver'] is True
    plan = stack.plan({'hardware': 'can_sim', 'can_interface': 'pcan', 'can_channel': '/t/l'})
    assert [s.name for s in plan][:2] == ['can_sim', 'driver']
    driver = plan[1].parameters
    assert (driver['can_interface'], driver['can_channel'], driver['enable_on_start']) == \
        ('cpr_usb2can', '/t/l', True)


def test_every_node_has_its_parameter_file():
    for choices in ({}, {'hardware': 'can_sim', 'rviz': 'true'}):
        nodes = {s.name for s in stack.plan(choices) if s.kind == 'node'}
        assert nodes <= set(stack.PARAMETER_FILES) <= set(NODES)


def test_the_namespace_prefixes_the_frames():
    for namespace, prefix in (('', ''), ('/', ''), ('arm2', 'arm2/'), ('/arm1', 'arm1/')):
        by_name = {s.name: s for s in stack.plan({'namespace': namespace})}
        assert by_name['state_publisher'].parameters == {'frame_prefix': prefix}


def test_launch_sh_lines_are_the_plan():
    """launch.sh's options (dashed hardware) give start lines with the plan's parameters."""
    text = stack.shell(['--hardware', 'can-sim', '--jog-units', 'fraction_of_max', '--rviz',
                        '--namespace', '/arm1'], can_channel='/t/link')
    assert 'hardware=can-sim' in text and 'can_channel=/t/link' in text
    body = text.split('start_stack() {\n')[1].split('\n}')[0].splitlines()
    plan = stack.plan({'hardware': 'can_sim', 'jog_units': 'fraction_of_max', 'rviz': 'true',
                       'namespace': '/arm1', 'can_channel': '/t/link'})
    assert len(body) == len(plan)
    assert body[0].strip() == 'start_can_sim' and body[-1].strip().startswith(
        'start_command rviz2')
    for line, start in zip(body[1:-1], plan[1:-1]):
        words = shlex.split(line.replace('${', '#{'))
        assert words[:3] == ['start', start.name, start.executable]
        given = dict(w.split(':=', 1) for w in words[3:] if ':=' in w)
        assert given == {k: stack.parameter_text(v) for k, v in start.parameters.items()}
        assert words[-1] == f'#{{{start.extra_args}:-}}'


def test_launch_sh_refuses_a_bad_choice_with_the_choices(capsys):
    with pytest.raises(SystemExit) as stop:
        stack.shell(['--hardware', 'can_sim'])
    assert stop.value.code == 2
    assert "--hardware must be one of: sim can-sim can; got 'can_sim'" in capsys.readouterr().err


def test_help_lists_every_choice():
    text = stack.parser().format_help()
    for option in stack.OPTIONS:
        if option.in_shell:
            assert option.flag in text
            for choice in option.choices if not option.switch else ():
                assert (choice.replace('_', '-') if option.dashed else choice) in text
