"""``realtime.steady_interpreter``: the timed nodes' start-up, and its undo for a test process."""

import gc
import sys

from mover6_control.realtime import steady_interpreter, SWITCH_INTERVAL


def test_it_sets_the_switch_interval_freezes_and_undoes_both():
    before = sys.getswitchinterval()
    loaded = [object() for _ in range(1000)]     # something loaded before the start
    undo = steady_interpreter()
    try:
        assert sys.getswitchinterval() == SWITCH_INTERVAL
        assert gc.get_freeze_count() >= len(loaded)
    finally:
        undo()
    assert sys.getswitchinterval() == before
    assert gc.get_freeze_count() == 0
