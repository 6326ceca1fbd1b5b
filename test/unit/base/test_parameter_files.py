"""
The generated parameter files say what the tables say (``mover6_control.parameter_files``).

A file read back by YAML gives every parameter of its node at its default, in the table's order;
each parameter's comment names its unit and every allowed value; the page has a row for every
parameter of every node.
"""

import re

from mover6_control.parameter_files import comment_of, markdown_text, yaml_text
from mover6_control.parameters import NODES
import pytest
import yaml


@pytest.mark.parametrize('node', sorted(NODES))
def test_a_parameter_file_reads_back_as_the_defaults(node):
    values = yaml.safe_load(yaml_text(node))[f'/**/{node}']['ros__parameters']
    assert list(values) == list(NODES[node]), 'same parameters, in the same order'
    for name, value in values.items():
        default = NODES[node][name].default
        assert (tuple(value) if isinstance(value, list) else value) == default, name
        assert type(value if not isinstance(value, list) else value[0]) is type(
            default if not isinstance(default, tuple) else default[0]), name


@pytest.mark.parametrize('node', sorted(NODES))
def test_each_comment_names_the_unit_and_every_allowed_value(node):
    text = yaml_text(node)
    for name, spec in NODES[node].items():
        comment = comment_of(spec)
        if spec.unit:
            assert comment.startswith(f'[{spec.unit}] ')
        assert [v for v in spec.allowed if not re.search(rf'\b{v}\b', comment)] == []
        # The comment is in the file, wrapped, right above the parameter.
        block = re.search(rf'((?:^    #.*\n)+)    {name}: ', text, re.M).group(1)
        assert ' '.join(line.strip()[2:] for line in block.splitlines()) == comment


def test_the_page_has_a_row_for_every_parameter():
    page = markdown_text()
    for node, table in NODES.items():
        section = re.search(rf'^## {node}\n(.*?)(?=^## |\Z)', page, re.M | re.S).group(1)
        assert re.findall(r'^\| `([\w.]+)` \|', section, re.M) == list(table), node
