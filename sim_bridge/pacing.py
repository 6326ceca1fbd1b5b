"""
Pacing a simulation against the wall clock: how many fixed physics steps are due now.

Pure: the caller keeps the anchor (the wall and sim time the pace counts from) and the clock.
"""

import math

from mover6_control.errors import InvalidInputError

_DUE_TOLERANCE = 1e-9   # [steps] a step that ends exactly now is due, whatever the rounding


def steps_due(sim_elapsed: float, wall_elapsed: float, real_time_factor: float,
              physics_dt: float, max_steps: int = 1000) -> int:
    """
    Return how many physics steps to run now to keep sim time at ``real_time_factor`` x wall.

    These are the steps that end by now: sim time never runs ahead of the paced wall time and
    lags it by less than one step. ``sim_elapsed`` and ``wall_elapsed`` [s] are counted from
    the same anchor. A factor of 0 means as fast as possible: ``max_steps`` every call. The
    result is in [0, max_steps]; a caller that gets ``max_steps`` while pacing has fallen
    behind and should re-anchor.
    """
    if not (math.isfinite(real_time_factor) and real_time_factor >= 0.0):
        raise InvalidInputError(f'real_time_factor must be >= 0, got {real_time_factor}')
    if real_time_factor == 0.0:
        return int(max_steps)
    behind = wall_elapsed * real_time_factor - sim_elapsed
    n = math.floor(behind / physics_dt + _DUE_TOLERANCE)
    return int(min(max(n, 0), max_steps))
