"""
Compile the package's numba kernels into their on-disk cache, once, after a build.

The time-optimal timing (``motion/timing``: ``greedy_scan``, ``topp_pieces``, ``arc_bounds``)
and the batch closed-form IK (``kinematics/ik_batch_kernel``) are compiled loops, compiled when
their module is imported and cached beside it (``__pycache__``). From the cache a node loads
them in about a second; without it the first node to import them compiles them (several
seconds, in the planner's and the controller's start-up). ``./run.sh`` runs this after each
build, so that no node compiles them: ``python -m mover6_control.tools.compile_kernels``
prints each module and how long it took to load.
"""

import importlib
import sys
import time
from typing import Optional, Sequence, TextIO

# Every module that compiles a kernel at import (its signature given: the functions it calls
# are compiled with it).
KERNEL_MODULES = ('mover6_control.motion.timing.greedy_scan',
                  'mover6_control.motion.timing.topp_pieces',
                  'mover6_control.motion.timing.arc_bounds',
                  'mover6_control.kinematics.ik_batch_kernel')


def compile_all(out: TextIO = sys.stdout) -> None:
    """Import every kernel module: what the cache lacks is compiled and cached."""
    for name in KERNEL_MODULES:
        started = time.perf_counter()
        importlib.import_module(name)
        print(f'{name}: {time.perf_counter() - started:.2f} s', file=out)


def main(argv: Optional[Sequence[str]] = None) -> None:
    """Compile the kernels (no arguments: ``argv`` is refused when it has any)."""
    if argv if argv is not None else sys.argv[1:]:
        sys.exit('compile_kernels takes no arguments')
    compile_all()


if __name__ == '__main__':
    main()
