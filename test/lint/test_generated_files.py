"""
The files made from the package's tables are committed as the generator writes them.

``config/<node>.yaml`` and ``docs/parameters.md`` come from ``mover6_control.parameters``
(``./run.sh generate``, ``mover6_control.parameter_files``): an edit of the table without
running the generator, or an edit of a generated file by hand, fails here.
"""

from mover6_control.tools.generate import differing
from source_tree import ROOT


def test_the_committed_files_are_the_generators_output():
    assert differing(ROOT) == [], 'run ./run.sh generate and commit the files it writes'
