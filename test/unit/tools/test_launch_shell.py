"""The launch shell: what launch.sh evaluates, from the parts it is made of, and its refusals."""

import os
import shlex

from ament_index_python.packages import get_package_prefix
from mover6_control import node_roles, stack
from mover6_control.nodes.runtime import local_dds
from mover6_control.tools import launch_shell
import pytest


def test_the_output_is_the_parts_in_order(capsys):
    assert launch_shell.main(['--', '--namespace', 'arm2', '--profile', 'continuous']) == 0
    out = capsys.readouterr().out
    values = stack.shell(['--namespace', 'arm2', '--profile', 'continuous'])
    assert out.startswith(f"prefix={get_package_prefix('mover6_control')}\n{values}")
    exports = ''.join(f'export {k}={shlex.quote(v)}\n'
                      for k, v in local_dds.default_environment(os.environ).items())
    assert out.endswith(exports + node_roles.shell() + 'namespace=/arm2\n')


def test_a_bad_namespace_is_refused_with_the_rule(capsys):
    assert launch_shell.main(['--', '--namespace', 'a b']) == 2
    captured = capsys.readouterr()
    assert captured.out == ''
    assert 'not a ROS namespace' in captured.err


def test_a_bad_option_is_refused_with_the_choices(capsys):
    with pytest.raises(SystemExit) as exit_info:
        launch_shell.main(['--', '--hardware', 'robot'])
    assert exit_info.value.code == 2
    assert 'must be one of' in capsys.readouterr().err
