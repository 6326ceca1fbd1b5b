"""
Skips that say so: every skipped or xfailed test of a run, by name, against a list of allowed ones.

``./run.sh test`` runs ``python test/skip_budget.py <pytest.xml>`` after the tests: it prints
every skipped test of the run by tier with its reason (a test that cannot run here: no network
namespace, no root, no real-time right ...), and an expected failure (xfail) the same way. A
skip or an xfail is allowed only by name, in ``test/skips_allowed.json``, with the reason it may
skip: any other fails the run (exit code 1), so a test that quietly stopped running is seen.
A run of part of the suite skips fewer, never more. When a skip is meant (a new test that cannot
run on the CI machine), add its name in the same commit, with why.

``skips_allowed.json`` has one list of names per network the run used (``MOVER6_TEST_NETWORK``,
which ``./run.sh test`` sets): ``netns`` (a private network namespace: every test runs) and
``host`` (the host network: the tests that start DDS without the loopback profile run only
inside a namespace and skip); and ``browser``, the console's browser tests, allowed to skip
only when the user says so with ``MOVER6_SKIP_BROWSER=1`` (a machine without Chromium where
nothing may be installed). A name is ``module::test`` (``test.e2e.test_x::test_y``; a
parametrized test by its name without the ``[...]``), or ``module::*``: every test of the
module.

The last line printed is the verdict; ``--summary FILE`` also writes it to FILE (``./run.sh
test`` prints it again as the run's last line).
"""

import json
import os
import sys
import xml.etree.ElementTree as ElementTree

ALLOWED = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'skips_allowed.json')
TIERS = {'unit': 'unit', 'node': 'node', 'e2e': 'e2e', 'lint': 'lint', 'architecture': 'lint'}
SKIP_BROWSER = 'MOVER6_SKIP_BROWSER'


def test_id(classname, name):
    """Return ``module::test`` of a junit test case ('mover6_control.' of colcon's dropped)."""
    module = classname.removeprefix('mover6_control.')
    return f'{module}::{name}'


def skipped(xml_path):
    """Return {tier: [(test id, reason, kind)]} of the skipped and xfailed tests of a run."""
    out = {tier: [] for tier in sorted(set(TIERS.values()))}
    for case in ElementTree.parse(xml_path).getroot().iter('testcase'):
        skip = case.find('skipped')
        if skip is None:
            continue
        kind = 'xfail' if skip.get('type') == 'pytest.xfail' else 'skip'
        # 'test.e2e.test_x' from pytest, 'mover6_control.test.e2e.test_x' from colcon test.
        parts = case.get('classname', '').split('.')
        folder = parts[parts.index('test') + 1] if 'test' in parts[:-1] else ''
        tier = TIERS.get(folder, 'unit')
        name = test_id(case.get('classname', ''), case.get('name', ''))
        out[tier].append((name, skip.get('message', '').strip() or '(no reason given)', kind))
    return out


def listed(name, names):
    """Return the entry of ``names`` that allows test ``name``, or None."""
    module, _, test = name.partition('::')
    base = test.split('[', 1)[0]
    for entry in (f'{module}::{test}', f'{module}::{base}', f'{module}::*'):
        if entry in names:
            return entry
    return None


def judge(found, allowed, network, skip_browser):
    """
    Return (not allowed, browser skips) of ``found``: lists of (test id, reason, kind).

    Allowed: a name in ``allowed[network]``, or in ``allowed['browser']`` when ``skip_browser``.
    """
    names = dict(allowed.get(network, {}))
    browser = allowed.get('browser', {})
    if skip_browser:
        names.update(browser)
    bad, browser_skips = [], []
    for tests in found.values():
        for item in tests:
            if listed(item[0], browser) is not None and item[2] == 'skip':
                browser_skips.append(item)
            if listed(item[0], names) is None:
                bad.append(item)
    return bad, browser_skips


def verdict(bad, browser_skips, skip_browser):
    """Return the one line that says whether the skips let the run count green."""
    if browser_skips and not skip_browser:
        return (f'NOT GREEN: {len(browser_skips)} browser tests skipped ({browser_skips[0][1]}); '
                f'{SKIP_BROWSER}=1 accepts that on a machine where nothing may be installed')
    if bad:
        return f'NOT GREEN: {len(bad)} tests skipped or xfailed that {os.path.basename(ALLOWED)}' \
               ' does not list'
    if browser_skips:
        return (f'{len(browser_skips)} browser tests skipped ({SKIP_BROWSER}=1): the console '
                'was not tested in a browser')
    return 'skips: only the listed ones'


def main(argv):
    """Print the skips of the run ``argv[0]``; return 1 when one is not allowed."""
    summary = None
    if argv[:1] == ['--summary']:
        summary, argv = argv[1], argv[2:]
    network = os.environ.get('MOVER6_TEST_NETWORK', 'host')
    skip_browser = os.environ.get(SKIP_BROWSER, '') == '1'
    with open(ALLOWED) as f:
        allowed = json.load(f)
    found = skipped(argv[0])
    counts = ', '.join(f'{tier} {len(tests)}' for tier, tests in sorted(found.items()))
    print(f'skipped or xfailed tests by tier (network {network}): {counts}')
    for tier, tests in sorted(found.items()):
        for name, reason, kind in tests:
            print(f'  {kind} ({tier}) {name}: {reason}')
    bad, browser_skips = judge(found, allowed, network, skip_browser)
    for name, reason, kind in bad:
        print(f'not allowed ({os.path.basename(ALLOWED)}): {kind} {name}: {reason}')
    line = verdict(bad, browser_skips, skip_browser)
    print(line)
    if summary:
        with open(summary, 'w') as f:
            f.write(line + '\n')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
