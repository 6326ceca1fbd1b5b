"""
Benchmarks of mover6_control: run all with ``./run.sh bench`` (python -m bench).

The benchmarks that start the nodes as processes use the test suite's process harness
(``test/ros_testing.py``), which lives with the tests and is put on the path here.
"""

import os
import sys

_TEST_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'test')
if _TEST_DIR not in sys.path:
    sys.path.insert(0, _TEST_DIR)
