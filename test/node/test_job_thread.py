"""The worker thread of the controller's demands and the planner's goals: in order, then closed."""

import threading

from mover6_control.nodes.runtime.job_thread import JobThread


def test_jobs_are_handled_in_order_in_the_thread_of_that_name():
    taken, threads, done = [], set(), threading.Event()

    def handle(job):
        taken.append(job)
        threads.add(threading.current_thread().name)
        if job == 'last':
            done.set()

    jobs = JobThread('demo_jobs', handle)
    for job in ('first', ('second', 2), 'last'):
        jobs.put(job)            # queued before the thread starts: kept, in order
    jobs.start()
    assert done.wait(10.0)
    assert taken == ['first', ('second', 2), 'last']
    assert threads == {'demo_jobs'}
    assert jobs.empty()
    jobs.close(10.0)
    assert not jobs.thread.is_alive()


def test_close_wakes_a_waiting_job_and_drops_the_queued_ones():
    event, started, taken = threading.Event(), threading.Event(), []

    def handle(job):
        taken.append(job)
        started.set()
        event.wait(30.0)         # a demand waiting for joint states
        taken.append(f'{job} woke: running={jobs.running}')

    jobs = JobThread('waiting_jobs', handle, wake=event.set)
    jobs.start()
    jobs.put('waits')
    assert started.wait(10.0)
    jobs.put('queued behind it')
    jobs.close(10.0)             # wakes the waiting job; the one behind it is not taken
    assert not jobs.thread.is_alive()
    assert taken == ['waits', 'waits woke: running=False']


def test_a_stopped_thread_takes_no_further_job():
    gate, first_taken, taken = threading.Event(), threading.Event(), []

    def handle(job):
        taken.append(job)
        first_taken.set()
        gate.wait(30.0)

    jobs = JobThread('stopped_jobs', handle)
    jobs.start()
    jobs.put('being taken')
    assert first_taken.wait(10.0)
    jobs.put('after the stop')
    jobs.stop()                  # the job being handled ends as it would
    gate.set()
    jobs.thread.join(10.0)       # the thread ends at the next job without taking it
    assert not jobs.thread.is_alive()
    assert taken == ['being taken']
