"""The skip budget of ./run.sh test (test/skip_budget.py): skips and xfails by name."""

import json

import pytest
import skip_budget

XML = """<?xml version="1.0"?><testsuites><testsuite>
<testcase classname="test.e2e.test_churn" name="test_a"><skipped type="pytest.skip"
 message="needs a private network namespace"/></testcase>
<testcase classname="test.e2e.test_churn" name="test_b"/>
<testcase classname="mover6_control.test.e2e.test_local_dds" name="test_e[x-y]"><skipped
 type="pytest.skip" message="only inside a namespace"/></testcase>
<testcase classname="test.architecture.test_layers" name="test_c"><skipped type="pytest.skip"
 message="no reason here"/></testcase>
<testcase classname="test.unit.x" name="test_d"><skipped type="pytest.xfail"
 message="expected"/></testcase>
</testsuite></testsuites>"""

BROWSER_XML = """<?xml version="1.0"?><testsuites><testsuite>
<testcase classname="test.e2e.test_e2e_console" name="test_page"><skipped type="pytest.skip"
 message="no /usr/bin/chromium"/></testcase>
</testsuite></testsuites>"""

ALL = {'test.e2e.test_churn::test_a': 'why', 'test.e2e.test_local_dds::test_e': 'why',
       'test.architecture.test_layers::test_c': 'why', 'test.unit.x::test_d': 'why'}


def write(tmp_path, name, text):
    """Write ``text`` to tmp_path/name; return its path."""
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.fixture
def run(tmp_path):
    """Return the path of a junit XML of a run with three skips and an xfail."""
    return write(tmp_path, 'pytest.xml', XML)


@pytest.fixture
def allowed(tmp_path, monkeypatch):
    """Return a function that writes the allowed list the budget reads."""
    path = tmp_path / 'allowed.json'
    monkeypatch.setattr(skip_budget, 'ALLOWED', str(path))
    monkeypatch.setenv('MOVER6_TEST_NETWORK', 'netns')
    monkeypatch.delenv('MOVER6_SKIP_BROWSER', raising=False)

    def write_allowed(netns, browser=None):
        path.write_text(json.dumps({'netns': netns, 'host': {}, 'browser': browser or {}}))
    return write_allowed


def test_skips_and_xfails_are_found_by_name_with_their_reason(run):
    found = skip_budget.skipped(run)
    assert found['e2e'] == [('test.e2e.test_churn::test_a', 'needs a private network namespace',
                             'skip'),
                            ('test.e2e.test_local_dds::test_e[x-y]', 'only inside a namespace',
                             'skip')]   # colcon's classnames too
    assert [n for n, _, _ in found['lint']] == ['test.architecture.test_layers::test_c']
    assert found['unit'] == [('test.unit.x::test_d', 'expected', 'xfail')]
    assert found['node'] == []


def test_every_listed_name_passes(run, allowed, capsys):
    allowed(ALL)
    assert skip_budget.main([run]) == 0
    out = capsys.readouterr().out
    assert 'needs a private network namespace' in out
    assert out.strip().splitlines()[-1] == 'skips: only the listed ones'


@pytest.mark.parametrize('missing', sorted(ALL))
def test_a_skip_or_xfail_not_listed_fails_the_run(run, allowed, capsys, missing):
    allowed({k: v for k, v in ALL.items() if k != missing})
    assert skip_budget.main([run]) == 1
    out = capsys.readouterr().out
    assert 'not allowed (allowed.json): ' in out and missing.split('::')[1] in out
    assert out.strip().splitlines()[-1].startswith('NOT GREEN: 1 tests')


def test_a_whole_module_is_allowed_by_its_star(tmp_path, allowed):
    allowed({'test.e2e.test_e2e_console::*': 'why'})
    assert skip_budget.main([write(tmp_path, 'b.xml', BROWSER_XML)]) == 0


def test_browser_skips_fail_unless_the_user_says_so(tmp_path, allowed, monkeypatch, capsys):
    allowed({}, browser={'test.e2e.test_e2e_console::*': 'no browser'})
    xml = write(tmp_path, 'b.xml', BROWSER_XML)
    summary = tmp_path / 'summary.txt'
    assert skip_budget.main(['--summary', str(summary), xml]) == 1
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith('NOT GREEN: 1 browser tests skipped (no /usr/bin/chromium)')
    assert 'MOVER6_SKIP_BROWSER=1' in last and summary.read_text().strip() == last
    monkeypatch.setenv('MOVER6_SKIP_BROWSER', '1')
    assert skip_budget.main([xml]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith('1 browser tests skipped (MOVER6_SKIP_BROWSER=1)')


def test_the_shipped_list_names_a_reason_for_every_entry():
    with open(skip_budget.ALLOWED) as f:
        allowed = json.load(f)
    assert set(allowed) == {'netns', 'host', 'browser'}
    for names in allowed.values():
        for name, reason in names.items():
            assert '::' in name and reason.strip(), name
