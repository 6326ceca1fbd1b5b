"""Run the ament flake8 linter over the package, as ament_python packages do."""

from ament_flake8.main import main_with_errors
import pytest

# Folders made by ./run.sh and colcon, not part of the source.
EXCLUDES = ['build', 'install', 'log', 'report', '.venv', '.colcon']


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8():
    rc, errors = main_with_errors(argv=['--exclude'] + EXCLUDES)
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
