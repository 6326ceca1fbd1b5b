"""
The files made from the package's tables are committed as the generator writes them.

``config/<node>.yaml`` and ``docs/parameters.md`` come from ``mover6_control.parameters``
(``./run.sh generate``, ``mover6_control.parameter_files``), the generated files of
``config/moveit/`` from the URDF, the collision checker, the driver's joint file and the table
(``mover6_control.tools.moveit_config``): an edit of a source without running the generator, or
an edit of a generated file by hand, fails here.
"""

from mover6_control.tools.generate import differing
from source_tree import ROOT


def test_the_committed_files_are_the_generators_output():
    assert differing(ROOT) == [], 'run ./run.sh generate and commit the files it writes'
