"""
The node tier: each test leaves the test process at normal scheduling, as it found it.

A node made with its shipped ``tick_priority`` or ``cycle_priority`` runs its timed thread at
SCHED_FIFO and every other thread of the process one below (``mover6_control.realtime``), the
test process's main thread among them. Left so, the rest of the suite ran at real-time
priority: a whole core taken from every other process on the machine (a second run beside it
saw its normal threads wait 100-170 ms).
"""

import os

import pytest

REAL_TIME = (os.SCHED_FIFO, os.SCHED_RR)


def normal_scheduling_everywhere():
    """Put every thread of this process that runs at real-time priority back to normal."""
    for tid in (int(t) for t in os.listdir('/proc/self/task')):
        try:
            policy = os.sched_getscheduler(tid) & ~getattr(os, 'SCHED_RESET_ON_FORK', 0)
            if policy in REAL_TIME:
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except ProcessLookupError:          # a thread that ended meanwhile
            pass


@pytest.fixture(autouse=True)
def normal_scheduling_after():
    """Run the test; then every thread of the process at normal scheduling again."""
    yield
    normal_scheduling_everywhere()
