"""
The controller's planning process (``nodes/controller/plan_worker.py``): the same plan.

A ``PlanJob`` run in the worker process gives the plan that ``job.run`` gives in this process,
bit for bit (its pickled form and its samples), for every kind of demand the controller plans:
10,000 waypoints of the continuous law, a start while moving, a timed goal, its time-optimal
fall-back, a stop-at-each profile; the collision guard's refusal comes back as the same error.
A worker that dies, takes too long or is closed raises ``PlanWorkerError`` with the reason, and
the next job is planned by a new worker. The jobs that die or sleep are doubles of a
``PlanJob`` (``run`` only, ``plan_worker_jobs``: light to import in the worker), inside this unit
test of ``PlanWorker``.
"""

import os
import pickle
import signal
import threading
import time

from mover6_control.collision.checker import CollisionSettings
from mover6_control.control.collision_guard import CollisionGuard
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.demand_intake import PlanJob
from mover6_control.control.timed_plan import Timing
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.controller.plan_worker import PlanWorker, PlanWorkerError
import numpy as np
from plan_worker_jobs import DyingJob, FailingJob, SlowJob
import pytest

ARM = mover6()
CORE = ControllerCore(ARM, ControllerConfig())
GUARD = CollisionGuard(ARM, CollisionSettings())


def smooth(n, amplitude=0.3):
    """Return ``n`` waypoints (n, 6) of a smooth excursion inside the limits, back to home."""
    s = np.sin(np.pi * np.linspace(0.0, 1.0, n))[:, None]
    return amplitude * s * np.array([1.0, -0.5, 0.5, 0.3, 0.4, -0.4])


def job(waypoints, q_start=None, qd_start=None, timing=None, profile=''):
    """Return the ``PlanJob`` the controller core makes of a demand."""
    return PlanJob(CORE.law_for(profile), np.zeros(6) if q_start is None else q_start,
                   CORE.check_demand(waypoints), CORE.core_state.derived.velocity_limits,
                   qd_start, timing, ARM.lower, ARM.upper)


@pytest.fixture(scope='module')
def worker():
    """One planning process for the module's tests."""
    planner = PlanWorker()
    yield planner
    planner.close()
    assert planner.process is None


def same_values(a, b, where='plan'):
    """Assert that ``a`` and ``b`` hold the same values bit for bit, all the way down."""
    assert type(a) is type(b), f'{where}: {type(a)} != {type(b)}'
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), f'{where}: the values differ'
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            same_values(x, y, f'{where}[{k}]')
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            same_values(a[k], b[k], f'{where}[{k!r}]')
    elif hasattr(a, '__dict__'):
        same_values(vars(a), vars(b), where)
    else:
        assert pickle.dumps(a) == pickle.dumps(b), f'{where}: {a!r} != {b!r}'


def same_plan(a, b):
    """Assert that two plans are the same bit for bit: every value in them, and samples."""
    same_values(a, b)
    assert a.duration == b.duration
    for t in np.linspace(-0.1, a.duration + 0.1, 2001):
        qa, qda = a.sample(t)
        qb, qdb = b.sample(t)
        assert np.array_equal(qa, qb) and np.array_equal(qda, qdb), t


JOBS = {
    'continuous, 10,000 waypoints': lambda: job(smooth(10000)),
    'continuous, from a moving start': lambda: job(
        smooth(300)[150:], q_start=smooth(300)[149], qd_start=np.full(6, 0.05)),
    'timed, followed': lambda: job(smooth(50)[1:], timing=Timing(np.linspace(0.2, 10.0, 49))),
    'timed, too fast: time-optimal': lambda: job(
        smooth(50)[1:], timing=Timing(np.linspace(0.001, 0.05, 49))),
    'synchronised, stop at each': lambda: job(smooth(40)[1:], profile='synchronised'),
    'trapezoidal, 2,000 waypoints': lambda: job(smooth(2000)[1:], profile='trapezoidal'),
}


@pytest.mark.parametrize('name', sorted(JOBS))
def test_the_worker_plans_the_same_plan_bit_for_bit(worker, name):
    """Each kind of demand: the worker's plan and note are this process's, bit for bit."""
    made = JOBS[name]()
    plan, note = worker(made, GUARD)
    here, note_here = made.run(GUARD)
    assert note == note_here
    same_plan(plan, here)


def test_a_collision_is_refused_with_the_same_reason(worker):
    """The collision guard runs in the worker: its refusal comes back as the same error."""
    down = np.array([[0.0, 1.4, 1.2, 0.0, 0.0, 0.0]])      # the tool into the table
    with pytest.raises(InvalidInputError) as here:
        job(down).run(GUARD)
    with pytest.raises(InvalidInputError) as there:
        worker(job(down), GUARD)
    assert str(there.value) == str(here.value) and 'collision' in str(there.value)


def test_a_dying_worker_refuses_the_job_and_the_next_is_planned(worker):
    """The worker killed mid-job: PlanWorkerError with the exit code; a new worker plans on."""
    first = worker.process.pid
    with pytest.raises(PlanWorkerError, match=r'died \(exit code -9\)'):
        worker(DyingJob())
    assert worker.process.pid != first and worker.process.is_alive()
    plan, _ = worker(job(smooth(20)), GUARD)
    same_plan(plan, job(smooth(20)).run(GUARD)[0])


def test_the_worker_is_out_of_reach_of_the_controllers_ctrl_c(worker):
    """A new session: a terminal's SIGINT to the controller's process group never reaches it."""
    pid = worker.process.pid
    assert os.getsid(pid) == pid != os.getsid(0)
    assert os.getpgid(pid) == pid != os.getpgid(0)


def test_ready_says_whether_the_worker_is_up():
    """ready() never waits: False while the worker starts, True once up; a dead one restarts."""
    planner = PlanWorker()
    try:
        assert wait_ready(planner)
        first = planner.process.pid
        os.kill(first, signal.SIGKILL)
        planner.process.join(10.0)
        assert not planner.ready()                  # dead: started again, not up yet
        assert planner.process.pid != first
        assert wait_ready(planner)
    finally:
        planner.close()
    assert not planner.ready()


def wait_ready(planner, timeout=60.0):
    """Return once ``planner.ready()`` (True), or False after ``timeout`` [s]."""
    deadline = time.monotonic() + timeout
    while not planner.ready() and time.monotonic() < deadline:
        time.sleep(0.05)
    return planner.ready()


def test_a_job_longer_than_the_timeout_is_refused_and_the_next_is_planned():
    """Past its timeout the job is refused with it, the worker restarted; the next job plans."""
    planner = PlanWorker(timeout=1.0, per_point=0.0)
    try:
        first = planner.process.pid
        started = time.monotonic()
        with pytest.raises(PlanWorkerError, match=r'longer than 1\.0 s'):
            planner(SlowJob(60.0))
        assert time.monotonic() - started < 20.0
        assert planner.process.pid != first and not os.path.exists(f'/proc/{first}')
        with pytest.raises(PlanWorkerError, match='Unpicklable: no pickle'):
            planner(FailingJob())
        plan, _ = planner(job(smooth(20)), GUARD)
        same_plan(plan, job(smooth(20)).run(GUARD)[0])
    finally:
        planner.close()


def test_close_ends_the_worker_and_a_waiting_job_is_refused(tmp_path):
    """close() while a job runs: the job raises 'closing', the process is gone, none restarts."""
    planner = PlanWorker()
    pid = planner.process.pid
    raised = []
    started = tmp_path / 'started'

    def plan():
        try:
            planner(SlowJob(60.0, str(started)))
        except PlanWorkerError as err:
            raised.append(str(err))
    thread = threading.Thread(target=plan)
    thread.start()
    deadline = time.monotonic() + 60.0
    while not started.exists() and time.monotonic() < deadline:   # the job runs in the worker
        time.sleep(0.01)
    assert started.exists()
    planner.close()
    thread.join(10.0)
    assert not thread.is_alive() and raised == ['the controller is closing'], raised
    assert planner.process is None and not os.path.exists(f'/proc/{pid}')
    with pytest.raises(PlanWorkerError, match='closing'):
        planner(job(smooth(20)))


def test_a_lazy_worker_starts_at_the_first_ready_or_job():
    """As the controller makes it (start=False): no process until asked, then it plans."""
    planner = PlanWorker(start=False)
    try:
        assert planner.process is None
        assert not planner.ready()                  # asked: it starts now, not up yet
        assert planner.process is not None and planner.restarts == 0
        assert wait_ready(planner)
        plan, _ = planner(job(smooth(20)), GUARD)
        same_plan(plan, job(smooth(20)).run(GUARD)[0])
    finally:
        planner.close()
    lazy = PlanWorker(start=False)
    try:
        plan, _ = lazy(job(smooth(20)), GUARD)     # a job starts it and waits for it
        same_plan(plan, job(smooth(20)).run(GUARD)[0])
        assert lazy.restarts == 0
    finally:
        lazy.close()
