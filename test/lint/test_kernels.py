"""
The list of compiled kernels that ``./run.sh`` compiles after a build names every one.

``tools.compile_kernels.KERNEL_MODULES`` is what the build compiles into numba's cache; a
module that compiles a kernel (``numba.njit``) and is not on it would be compiled by the first
node that imports it, at its start. Read from the sources, not imported.
"""

import os

from mover6_control.tools.compile_kernels import KERNEL_MODULES
import pytest
from source_tree import ROOT

pytestmark = pytest.mark.lint


def modules_with_kernels():
    """Return the package's modules (dotted) whose source compiles a numba kernel."""
    found = set()
    top = os.path.join(ROOT, 'mover6_control')
    for folder, _, files in os.walk(top):
        for name in files:
            if name.endswith('.py'):
                path = os.path.join(folder, name)
                with open(path, encoding='utf-8') as f:
                    if 'numba.njit' in f.read():
                        relative = os.path.relpath(path, ROOT)[:-3]
                        found.add(relative.replace(os.sep, '.'))
    return found


def test_every_kernel_module_is_compiled_after_a_build():
    kernels = modules_with_kernels()
    assert kernels, 'no module compiles a kernel: the list and this test should go'
    assert kernels == set(KERNEL_MODULES), kernels ^ set(KERNEL_MODULES)
