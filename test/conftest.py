"""
Test-wide settings and the process harness of the end-to-end tests.

DDS discovery stays on loopback, and each test run gets its own ROS domain (./run.sh test picks
one; a bare pytest run picks one here), so parallel runs on one machine never see each other.
"""

import os
import random

# Before anything imports rclpy: these are read when a context is created.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('MPLBACKEND', 'Agg')
os.environ.setdefault('PYTHONDONTWRITEBYTECODE', '1')


# Property tests: random examples for developers; in CI the same examples every run, so a
# failure there is reproducible (hypothesis prints the blob to reproduce it).
from hypothesis import settings  # noqa: E402

settings.register_profile('ci', derandomize=True, print_blob=True)
if os.environ.get('CI'):
    settings.load_profile('ci')
