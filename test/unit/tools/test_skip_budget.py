"""The skip budget of ./run.sh test (test/skip_budget.py): skips by tier, with their reasons."""

import json

import pytest
import skip_budget

XML = """<?xml version="1.0"?><testsuites><testsuite>
<testcase classname="test.e2e.test_churn" name="test_a"><skipped type="pytest.skip"
 message="needs a private network namespace"/></testcase>
<testcase classname="test.e2e.test_churn" name="test_b"/>
<testcase classname="mover6_control.test.e2e.test_local_dds" name="test_e"><skipped
 type="pytest.skip" message="only inside a namespace"/></testcase>
<testcase classname="test.architecture.test_layers" name="test_c"><skipped type="pytest.skip"
 message="no reason here"/></testcase>
<testcase classname="test.unit.x" name="test_d"><skipped type="pytest.xfail"
 message="expected"/></testcase>
</testsuite></testsuites>"""


@pytest.fixture
def run(tmp_path):
    """Return the path of a junit XML of a run with two skips and an xfail."""
    path = tmp_path / 'pytest.xml'
    path.write_text(XML)
    return str(path)


def test_skips_are_counted_by_tier_with_their_reason(run):
    found = skip_budget.skipped(run)
    assert found['e2e'] == [('test.e2e.test_churn::test_a', 'needs a private network namespace'),
                            ('mover6_control.test.e2e.test_local_dds::test_e',
                             'only inside a namespace')]   # colcon's classnames too
    assert [n for n, _ in found['lint']] == ['test.architecture.test_layers::test_c']
    assert found['unit'] == [] and found['node'] == []          # an xfail is no skip


def test_a_tier_over_its_count_fails(run, tmp_path, monkeypatch, capsys):
    allowed = tmp_path / 'allowed.json'
    monkeypatch.setattr(skip_budget, 'ALLOWED', str(allowed))
    monkeypatch.setenv('MOVER6_TEST_NETWORK', 'netns')
    allowed.write_text(json.dumps({'netns': {'unit': 0, 'node': 0, 'e2e': 2, 'lint': 1},
                                   'host': {'unit': 0, 'node': 0, 'e2e': 0, 'lint': 0}}))
    assert skip_budget.main([run]) == 0
    out = capsys.readouterr().out
    assert 'e2e 2/2' in out and 'needs a private network namespace' in out
    allowed.write_text(json.dumps({'netns': {'unit': 0, 'node': 0, 'e2e': 0, 'lint': 1},
                                   'host': {'unit': 0, 'node': 0, 'e2e': 9, 'lint': 9}}))
    assert skip_budget.main([run]) == 1
    assert 'more skips than before: e2e: 2 skipped, 0 allowed' in capsys.readouterr().out
