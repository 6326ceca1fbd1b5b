"""
The controller's planning process: a large demand is planned outside the controller's process.

Timing 10,000 waypoints (the time-optimal solver, the collision check of the motion) takes
seconds of CPU. Done in the controller's demand thread, it held the interpreter lock in long
numpy calls, and on a loaded machine also while it waited for a CPU: the tick thread waited
behind it (ticks 0.1-0.26 s apart, and a '/joint_states stale' fault of the controller's own
making while the states kept coming). ``PlanWorker`` runs the demand's ``PlanJob``
(``control.demand_intake``) in a child process (a new Python, never a fork of a process with DDS
threads), which the controller starts at its first large demand (a controller that never gets
one never pays for a second Python with numpy and scipy), and returns the same plan, bit for bit:
the job and the collision guard go there pickled, the plan comes back pickled (``BlendedPath``
pickles as a few arrays, so taking it back is short), and an exception the job raises there is
raised here.

A worker that dies, or that takes longer than ``timeout + per_point`` per waypoint, raises
``PlanWorkerError`` with the reason (the controller refuses the demand with it, and goes on) and
is started again for the next demand. One job at a time, in the order they come (the demand
thread's). ``close`` ends the worker (SIGKILL: it keeps nothing); a job waiting for it then
raises. The worker runs in a session of its own: a terminal's Ctrl-C and a launcher's signal to
the controller's process group never reach it (not even while it loads numpy, when a SIGINT
ended it with a traceback), the controller ends it by pid, after its last zero command; and it
ends by itself when the controller's end of its socket closes (the controller died).

No ROS here and none in the worker: it imports the core's planning only.
"""

from multiprocessing.connection import Connection
import os
import pickle
import signal
import socket
import subprocess
import sys
import threading
from typing import Callable, Optional

from mover6_control.control.demand_intake import PlanJob
from mover6_control.errors import Mover6Error

# [s] longest planning of a demand, plus PER_POINT per waypoint (10,000 waypoints: 45 s; the
# action waits 60 s for them, trajectory_server.ACCEPT_TIMEOUT): then the worker is restarted
# and the demand refused. 10,000 waypoints take 5 s of CPU on the development machine.
TIMEOUT = 5.0
PER_POINT = 0.004
# [s] longest start of the worker process (Python, numpy, scipy: seconds on a loaded machine),
# before its first job's timeout counts.
START_TIMEOUT = 30.0
READY = b'ready'
# [s] how long ``close`` waits for the worker to be gone after SIGKILL.
CLOSE_WAIT = 2.0
PROTOCOL = pickle.HIGHEST_PROTOCOL


class PlanWorkerError(Mover6Error):
    """The planning process could not plan the demand (died, too slow, closed): the reason."""


class WorkerProcess:
    """
    The worker process: a new Python in a session of its own, its end of a socket pair at ``fd``.

    It offers what ``PlanWorker`` and its tests use of a process: ``pid``, ``is_alive``,
    ``kill``, ``join`` and ``exitcode`` (negative: the signal that ended it).
    """

    COMMAND = ('import sys; from mover6_control.nodes.controller.plan_worker import main; '
               'main(int(sys.argv[1]))')

    def __init__(self, fd: int):
        """Start the worker with its end of the socket pair at ``fd`` (inherited)."""
        env = dict(os.environ)
        # The same modules as here: the worker unpickles the job's classes.
        env['PYTHONPATH'] = os.pathsep.join(p for p in sys.path if p)
        self._popen = subprocess.Popen(
            [sys.executable, '-c', self.COMMAND, str(fd)], pass_fds=(fd,), env=env,
            stdin=subprocess.DEVNULL, start_new_session=True, close_fds=True)
        self.pid = self._popen.pid

    def is_alive(self) -> bool:
        """Return whether the process still runs."""
        return self._popen.poll() is None

    def kill(self) -> None:
        """Send it SIGKILL."""
        if self.is_alive():
            self._popen.kill()

    def join(self, timeout: Optional[float] = None) -> None:
        """Wait up to ``timeout`` [s] for it to end."""
        try:
            self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            pass

    @property
    def exitcode(self) -> Optional[int]:
        """Return the code it ended with (None while it runs)."""
        return self._popen.poll()


def main(fd: int) -> None:
    """Serve the socket at ``fd`` until the controller closes it: the worker process's entry."""
    serve(Connection(fd))


def serve(conn: Connection) -> None:
    """
    Run jobs from ``conn`` until it closes: the worker process's main loop.

    It says ``READY`` once the planning modules are loaded. A job is ``pickle((job, guard))``;
    the answer ``pickle(('plan', job.run(guard)))``, or
    ``('raise', exception)`` when it raised (``('error', text)`` when that does not pickle).
    """
    for signum in (signal.SIGINT, signal.SIGTERM):   # the controller ends it, by pid
        signal.signal(signum, signal.SIG_IGN)
    conn.send_bytes(READY)      # the planning modules are loaded (this module imports them)
    while True:
        try:
            job, guard = pickle.loads(conn.recv_bytes())
        except (EOFError, OSError):
            return                                   # the controller closed its end
        try:
            answer = pickle.dumps(('plan', job.run(guard)), PROTOCOL)
        except Exception as err:  # noqa: B902 - every failure goes back to the demand
            try:
                answer = pickle.dumps(('raise', err), PROTOCOL)
                pickle.loads(answer)
            except Exception:  # noqa: B902 - an exception that does not pickle: its text
                answer = pickle.dumps(('error', f'{type(err).__name__}: {err}'), PROTOCOL)
        try:
            conn.send_bytes(answer)
        except OSError:
            return


class PlanWorker:
    """A planning process of the controller (module docstring); call it as a ``Planner``."""

    def __init__(self, timeout: float = TIMEOUT, per_point: float = PER_POINT,
                 start: bool = True):
        """Start the worker process now, or with ``start`` False at the first ``ready`` or job."""
        self.timeout, self.per_point = timeout, per_point
        self._busy = threading.Lock()    # one job at a time
        self._state = threading.Lock()   # process, conn and closed, swapped together
        self.closed = False
        self.process = None
        self._conn = None
        self.restarts = 0
        self._ready = False              # the worker said READY
        if start:
            self._start()

    def _start(self) -> None:
        """Start a worker process (none when closed)."""
        ours, theirs = socket.socketpair()
        with self._state:
            if not self.closed:
                self.process = WorkerProcess(theirs.fileno())
                self._conn = Connection(ours.detach())
                self._ready = False
        ours.close()
        theirs.close()

    def _restart(self) -> None:
        """End the worker (it may be busy with a job given up on) and start a new one."""
        with self._state:
            process, conn = self.process, self._conn
            self.process = self._conn = None
        _end(process)
        if conn is not None:
            conn.close()
        self.restarts += process is not None      # the first start of a lazy worker is none
        self._start()

    def ready(self) -> bool:
        """
        Return whether the worker is up (it said ``READY``), without waiting.

        A worker that died is started again (it is not ready then). While it starts (seconds
        at the node's start, on a loaded machine) the controller plans in its own process.
        """
        with self._busy:
            with self._state:
                process, conn = self.process, self._conn
                if self.closed:
                    return False
            if process is None or not process.is_alive():
                self._restart()
                return False
            if not self._ready:
                try:
                    self._ready = conn.poll(0) and conn.recv_bytes() == READY
                except (EOFError, OSError):
                    return False
            return self._ready

    def job_timeout(self, job: PlanJob) -> float:
        """Return the longest planning [s] of ``job`` (``timeout`` + ``per_point`` each)."""
        return self.timeout + self.per_point * len(job.waypoints)

    def __call__(self, job: PlanJob, guard: Optional[Callable] = None) -> tuple:
        """
        Return ``job.run(guard)`` made in the worker process; raise as it raises there.

        Raises ``PlanWorkerError`` when the worker dies, takes longer than ``job_timeout``, or
        the node closes meanwhile; the worker is started again for the next job.
        """
        payload = pickle.dumps((job, guard), PROTOCOL)
        timeout = self.job_timeout(job)
        with self._busy:
            with self._state:
                if self.closed:
                    raise PlanWorkerError('the controller is closing')
                process, conn = self.process, self._conn
            if process is None or not process.is_alive():
                self._restart()
                with self._state:
                    process, conn = self.process, self._conn
                if process is None:
                    raise PlanWorkerError('the controller is closing')
            try:
                if not self._ready:
                    if not conn.poll(START_TIMEOUT) or conn.recv_bytes() != READY:
                        self._restart()
                        raise PlanWorkerError(f'the planning process did not start within '
                                              f'{START_TIMEOUT:g} s (it was started again)')
                    self._ready = True
                conn.send_bytes(payload)
                if not conn.poll(timeout):
                    self._restart()
                    raise PlanWorkerError(f'planning took longer than {timeout:.1f} s (the '
                                          f'planning process was started again)')
                answer = conn.recv_bytes()
            except (EOFError, OSError):
                if self.closed:
                    raise PlanWorkerError('the controller is closing') from None
                process.join(CLOSE_WAIT)
                code = process.exitcode
                self._restart()
                raise PlanWorkerError(f'the planning process died (exit code {code}); it was '
                                      f'started again') from None
        kind, value = pickle.loads(answer)
        if kind == 'plan':
            return value
        if kind == 'raise':
            raise value
        raise PlanWorkerError(f'planning failed: {value}')

    def close(self) -> None:
        """End the worker process (a job waiting for it raises ``PlanWorkerError``)."""
        with self._state:
            self.closed = True
            process = self.process
        _end(process)
        # The pipe is closed by whoever holds it: here once a job waiting for it gave up.
        if self._busy.acquire(timeout=CLOSE_WAIT):
            try:
                with self._state:
                    conn, self.process, self._conn = self._conn, None, None
                if conn is not None:
                    conn.close()
            finally:
                self._busy.release()


def _end(process) -> Optional[int]:
    """End ``process`` (SIGKILL: it ignores SIGTERM); return its exit code."""
    if process is None:
        return None
    if process.is_alive():
        process.kill()
        process.join(CLOSE_WAIT)
    return process.exitcode
