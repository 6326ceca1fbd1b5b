"""
Test-wide settings and the process harness of the end-to-end tests.

DDS discovery stays on loopback, and each test run gets its own ROS domain (./run.sh test picks
one; a bare pytest run picks one here), so parallel runs on one machine never see each other.

Property tests (hypothesis) draw the same examples on every run, here as in CI, so a failure is
reproducible and a user meets the failures CI meets. Random exploration on request:
``MOVER6_HYPOTHESIS_RANDOM=1`` draws new examples from a seed, printed in the test header;
``MOVER6_HYPOTHESIS_SEED=<seed>`` with it draws those examples again.
"""

import os
import random

# Before anything imports rclpy: these are read when a context is created.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('MPLBACKEND', 'Agg')
os.environ.setdefault('PYTHONDONTWRITEBYTECODE', '1')

from hypothesis import core, settings  # noqa: E402

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


# Tiers (./run.sh test -m unit | node | e2e | lint): a test module marked e2e starts processes;
# one that holds rclpy or ROS messages spins nodes in this process (node); the checks of the
# source itself (style, layers, one home) are lint; everything else tests the ROS-free core.
LINT_MODULES = {'test_flake8', 'test_pep257', 'test_layers', 'test_core_is_ros_free',
                'test_one_home', 'test_status_schema'}
# Modules that start processes without the e2e marker on each test (run.sh in a sandbox).
PROCESS_MODULES = {'test_run_sh'}


def _uses_ros(module):
    for value in vars(module).values():
        name = getattr(value, '__module__', None) or getattr(value, '__name__', '') or ''
        if isinstance(name, str) and (name.split('.')[0] == 'rclpy' or '_msgs.' in name
                                      or '_srvs.' in name or name.startswith('ros_testing')):
            return True
    return False


def pytest_collection_modifyitems(config, items):
    """Mark every test with its tier (unit, node, e2e, lint) unless it is marked already."""
    import pytest
    tiers = {}
    for item in items:
        if any(item.get_closest_marker(t) for t in ('e2e', 'node', 'lint', 'unit')):
            continue
        module = item.module
        if module not in tiers:
            short = module.__name__.rsplit('.', 1)[-1]
            tiers[module] = ('lint' if short in LINT_MODULES
                             else 'e2e' if short in PROCESS_MODULES
                             else 'node' if _uses_ros(module) else 'unit')
        item.add_marker(getattr(pytest.mark, tiers[module]))
