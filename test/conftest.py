"""
Test-wide settings and the process harness of the end-to-end tests.

DDS stays on loopback, and each test run gets its own ROS domain (./run.sh test picks
one; a bare pytest run picks one here), so parallel runs on one machine never see each other.

Property tests (hypothesis) draw the same examples on every run, here as in CI, so a failure is
reproducible and a user meets the failures CI meets. Random exploration on request:
``MOVER6_HYPOTHESIS_RANDOM=1`` draws new examples from a seed, printed in the test header;
``MOVER6_HYPOTHESIS_SEED=<seed>`` with it draws those examples again.
"""

import os
import random

from hypothesis import core, settings
from mover6_control.nodes.runtime import local_dds

# Before anything imports rclpy: these are read when a context is created. DDS as the launchers
# set it (./run.sh test has already): the package's loopback-only configuration unless the user
# chose their own (ROS_AUTOMATIC_DISCOVERY_RANGE, ..., MOVER6_DDS=localhost).
local_dds.apply_default(os.environ)
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('MPLBACKEND', 'Agg')
os.environ.setdefault('PYTHONDONTWRITEBYTECODE', '1')
# run.sh keeps this process's bytecode in the workspace (PYTHONPYCACHEPREFIX); the processes the
# tests start must not look there: with a prefix Python ignores every __pycache__ beside the
# sources, so each node compiled rclpy, numpy and scipy again (4-5 s more per start).
os.environ.pop('PYTHONPYCACHEPREFIX', None)

RANDOM_ENV, SEED_ENV = 'MOVER6_HYPOTHESIS_RANDOM', 'MOVER6_HYPOTHESIS_SEED'
settings.register_profile('ci', derandomize=True, print_blob=True)
settings.register_profile('random', derandomize=False, print_blob=True)
if os.environ.get(RANDOM_ENV, '') not in ('', '0'):
    HYPOTHESIS_SEED = int(os.environ.get(SEED_ENV) or random.SystemRandom().randrange(2 ** 32))
    settings.load_profile('random')
    # What pytest's --hypothesis-seed option sets: every property test draws from this seed.
    core.global_force_seed = HYPOTHESIS_SEED
else:
    HYPOTHESIS_SEED = None
    settings.load_profile('ci')


def pytest_report_header(config):
    """Say which hypothesis examples this run draws (and how to draw them again)."""
    if HYPOTHESIS_SEED is None:
        return (f'hypothesis: the same examples every run (derandomized); {RANDOM_ENV}=1 '
                'draws random ones')
    return (f'hypothesis: random examples, seed {HYPOTHESIS_SEED} (again: {RANDOM_ENV}=1 '
            f'{SEED_ENV}={HYPOTHESIS_SEED})')


def pytest_terminal_summary(terminalreporter):
    """Repeat a random run's seed at the end, where a failure is read."""
    if HYPOTHESIS_SEED is not None:
        terminalreporter.write_line(pytest_report_header(None))


# Tiers (./run.sh test -m unit | node | e2e | lint, or a folder: ./run.sh test test/unit): a
# test's folder is its tier, and a tier marker that names another tier is refused at collection.
# unit/<layer>/ tests the ROS-free core layer by layer in this process (no rclpy, no process);
# node/ spins real rclpy nodes (or ROS messages) in this process; e2e/ starts processes; lint/
# and architecture/ check the source itself (style; layers and schema), both marked lint.
TIER_MARKERS = {'unit': ('unit',), 'node': ('node',), 'e2e': ('e2e',), 'lint': ('lint',),
                'architecture': ('lint', 'architecture')}
TEST_DIR = os.path.dirname(os.path.abspath(__file__))


def tier_of(path):
    """Return the tier folder of a test file (its first folder below test/)."""
    folder = os.path.relpath(str(path), TEST_DIR).split(os.sep)[0]
    if folder not in TIER_MARKERS:
        raise ValueError(f'{path}: a test belongs in a tier folder of test/ '
                         f'({", ".join(TIER_MARKERS)})')
    return folder


def pytest_collection_modifyitems(config, items):
    """Mark every test with its folder's tier (unit, node, e2e, lint); refuse another's mark."""
    import pytest
    for item in items:
        try:
            tier = tier_of(item.path)
        except ValueError as err:
            raise pytest.UsageError(str(err)) from None
        wrong = [t for t in ('e2e', 'node', 'lint', 'unit')
                 if item.get_closest_marker(t) and t not in TIER_MARKERS[tier]]
        if wrong:
            raise pytest.UsageError(f'{item.nodeid}: marked {wrong[0]} in the {tier} folder; '
                                    "a test's folder is its tier: move it")
        for marker in TIER_MARKERS[tier]:
            if not item.get_closest_marker(marker):
                item.add_marker(getattr(pytest.mark, marker))
