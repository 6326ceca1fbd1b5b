"""
``mover6_control.realtime``: the one place that raises a timed thread to SCHED_FIFO.

Tried in a child process (raising a thread of the test process would raise all its threads).
Where the system refuses real-time scheduling, the refusal must come back as a reason.
"""

import json
import subprocess
import sys

from mover6_control.realtime import run_at_priority
import pytest

pytestmark = pytest.mark.unit

CHILD = """
import json, threading
from mover6_control.realtime import run_at_priority, scheduling_of_thread
out = {}
def timed():
    out['result'] = run_at_priority(20)
    out['timed'] = scheduling_of_thread()
thread = threading.Thread(target=timed)
thread.start()
thread.join()
out['main'] = scheduling_of_thread()
print(json.dumps(out))
"""


def test_priority_zero_and_bad_values_change_nothing():
    assert run_at_priority(0) == (False, 'off')
    assert run_at_priority(-3) == (False, 'off')
    ok, reason = run_at_priority(True)
    assert not ok and 'int' in reason
    ok, reason = run_at_priority(2.5)
    assert not ok and 'int' in reason


def test_the_timed_thread_runs_fifo_and_the_others_just_below_or_the_refusal_says_why():
    done = subprocess.run([sys.executable, '-c', CHILD], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    ok, message = out['result']
    if ok:
        assert out['timed'] == ['fifo', 20]
        assert out['main'] == ['fifo', 19]
        assert 'SCHED_FIFO priority 20' in message
    else:
        assert 'refused' in message and out['timed'][0] == 'other'


def test_a_process_started_from_a_fifo_thread_runs_at_normal_priority():
    main = "out['main'] = scheduling_of_thread()"
    child = CHILD.replace(main, main + """
import subprocess, sys
probe = 'import os; print(os.sched_getscheduler(0))'
out['child'] = subprocess.run([sys.executable, '-c', probe], capture_output=True,
                              text=True).stdout.strip()""")
    done = subprocess.run([sys.executable, '-c', child], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert int(out['child']) == 0           # SCHED_OTHER
