"""
``mover6_control.realtime``: the one place that raises a timed thread to SCHED_FIFO.

Tried in a child process (raising a thread of the test process would raise all its threads):
an e2e test, as every test that starts a process.
Where the system refuses real-time scheduling, the refusal must come back as a reason.
"""

import json
import subprocess
import sys

from mover6_control.realtime import run_at_priority
from ros_testing import without_the_right

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


WITHOUT_THE_RIGHT = """
import json, threading
from mover6_control.realtime import raise_this_thread, scheduling_of_thread
lines = []
class Log:
    def info(self, text):
        lines.append(['info', text])
    def warning(self, text):
        lines.append(['warning', text])
out = {}
def timed():
    out['raised'] = raise_this_thread(50, Log(), 'tick', 'tick_priority')
    out['timed'] = scheduling_of_thread()
thread = threading.Thread(target=timed)
thread.start()
thread.join()
out['main'] = scheduling_of_thread()
out['lines'] = lines
print(json.dumps(out))
"""


def test_without_the_right_the_thread_runs_on_and_one_line_says_why():
    """The fall-back: normal scheduling, one warning naming the parameter, how to allow it."""
    done = subprocess.run([sys.executable, '-c', WITHOUT_THE_RIGHT], capture_output=True,
                          text=True, timeout=60, preexec_fn=without_the_right)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out['raised'] is False
    assert out['timed'] == ['other', 0] and out['main'] == ['other', 0]
    assert len(out['lines']) == 1, out['lines']
    level, text = out['lines'][0]
    assert level == 'warning'
    assert text.startswith('tick_priority 50: real-time scheduling refused'), text
    assert 'normal priority' in text and 'rtprio' in text, text
