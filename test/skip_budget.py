"""
Skips that say so (issue 31): each tier's skipped tests with their reasons, against a budget.

``./run.sh test`` runs ``python test/skip_budget.py <pytest.xml>`` after the tests: it prints
every skipped test of the run by tier with its reason (a test that cannot run here: no network
namespace, no root, no real-time right ...) and the count of each tier against
``test/skips_allowed.json``, the counts of a whole run kept in the repository. A tier that skips
more than its count fails the run (exit code 1): a test that quietly stopped running is seen.
A run of part of the suite skips fewer, never more. When a skip is meant (a new test that cannot
run on the CI machine), raise the count in the same commit, saying why.

The counts are kept per network the run used (``MOVER6_TEST_NETWORK``, which ``./run.sh test``
sets): ``netns`` (a private network namespace: every test runs) and ``host`` (the host network:
the tests that start DDS without the loopback profile run only inside a namespace and skip).
"""

import json
import os
import sys
import xml.etree.ElementTree as ElementTree

ALLOWED = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'skips_allowed.json')
TIERS = {'unit': 'unit', 'node': 'node', 'e2e': 'e2e', 'lint': 'lint', 'architecture': 'lint'}


def skipped(xml_path):
    """Return {tier: [(test, reason)]} of the skipped tests in a pytest junit XML file."""
    out = {tier: [] for tier in sorted(set(TIERS.values()))}
    for case in ElementTree.parse(xml_path).getroot().iter('testcase'):
        skip = case.find('skipped')
        if skip is None or skip.get('type') == 'pytest.xfail':
            continue
        # 'test.e2e.test_x' from pytest, 'mover6_control.test.e2e.test_x' from colcon test.
        parts = case.get('classname', '').split('.')
        folder = parts[parts.index('test') + 1] if 'test' in parts[:-1] else ''
        tier = TIERS.get(folder, 'unit')
        name = f'{case.get("classname")}::{case.get("name")}'
        out[tier].append((name, skip.get('message', '').strip() or '(no reason given)'))
    return out


def over_budget(found, allowed):
    """Return the lines that say which tiers skip more than ``allowed``."""
    return [f'{tier}: {len(tests)} skipped, {allowed.get(tier, 0)} allowed '
            f'({os.path.basename(ALLOWED)})'
            for tier, tests in sorted(found.items()) if len(tests) > allowed.get(tier, 0)]


def main(argv):
    """Print the skips of the run ``argv[0]`` by tier; return 1 when a tier is over budget."""
    network = os.environ.get('MOVER6_TEST_NETWORK', 'host')
    with open(ALLOWED) as f:
        allowed = json.load(f)[network]
    found = skipped(argv[0])
    counts = ', '.join(f'{tier} {len(tests)}/{allowed.get(tier, 0)}'
                       for tier, tests in sorted(found.items()))
    print(f'skipped tests by tier (skipped/allowed, network {network}): {counts}')
    for tier, tests in sorted(found.items()):
        for name, reason in tests:
            print(f'  skipped ({tier}) {name}: {reason}')
    over = over_budget(found, allowed)
    for line in over:
        print(f'more skips than before: {line}')
    return 1 if over else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
