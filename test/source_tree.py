"""The source tree's top folder, for the tests that read its files (every tier folder)."""

import os

# This module sits in test/, one level below the top, whatever folder the test is in.
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
