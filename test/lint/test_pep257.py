"""Run the ament pep257 docstring linter over the package."""

from ament_pep257.main import main
import pytest

EXCLUDES = ['build', 'install', 'log', 'report', '.venv', '.colcon']


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=['.', 'test', '--exclude'] + EXCLUDES)
    assert rc == 0, 'Found code style errors / warnings'
