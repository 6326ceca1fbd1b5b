"""
Real-time scheduling for the one thread of a process that keeps time (SCHED_FIFO, where allowed).

The controller's tick thread (``tick_priority``) and the driver's cycle thread
(``cycle_priority``) both call ``run_at_priority`` from the thread itself, as ros2_control's
controller manager raises its update thread. In Python the timed thread also needs the
interpreter lock: when another thread of the process holds it (the executor, a publisher) and
waits for a CPU behind the machine's other processes, the timed thread waits with it. So every
other thread of the process runs at SCHED_FIFO ``priority - 1`` (at least 1). Threads and
processes started later from any of them run at normal priority (SCHED_RESET_ON_FORK holds for
every new task, threads included). Where the system refuses it (no
CAP_SYS_NICE, no rtprio limit) nothing changes and the caller is told why, to say so once and go
on.

A SCHED_FIFO thread runs until it blocks: one that never sleeps takes a whole CPU from every
normal process (the kernel's real-time throttling leaves them 5 %). So each timed thread sleeps
between its periods even when it runs late (the tick rests a tenth of a period, the
physics thread after an overrun), and the physics thread runs unpaced (``real_time_factor``
0, as fast as it can) at normal scheduling (``run_normal``).

``steady_interpreter`` is the rest of a timed process's start-up (the controller's and the
driver's ``main()``; the in-process tests of those nodes call it too, and undo it after): the
interpreter lock changes hands every ``SWITCH_INTERVAL`` (Python's default is 5 ms), and what is
loaded at start is frozen out of the garbage collector (a full collection of it took 0.1 s and
more, with every thread of the process waiting).
"""

from __future__ import annotations

import ctypes
import gc
import os
import sys
import threading
from typing import Any, Callable

MIN_PRIORITY, MAX_PRIORITY = 1, 99
"""The SCHED_FIFO priorities Linux offers; 0 means 'normal scheduling' to the callers."""
SWITCH_INTERVAL = 0.0005
"""[s] the interpreter lock's switch interval in a timed process (module docstring)."""
BLAS_SET_THREADS = ('openblas_set_num_threads', 'scipy_openblas_set_num_threads64_',
                    'scipy_openblas_set_num_threads', 'openblas_set_num_threads64_')
"""The names OpenBLAS builds (numpy's own is scipy-openblas) give its thread count setter."""


def blas_on_one_thread() -> int:
    """
    Let every OpenBLAS loaded in this process compute on its caller's thread only.

    OpenBLAS's worker threads busy-wait for new work for a while after each call. Raised with
    the rest of the process (one below the timed thread) such a worker keeps a CPU from every
    normal process and, on two cores, from the thread holding the interpreter lock the timed
    thread waits for: with it, ``bench churn``'s tick gaps at motion starts were 50-150 ms
    (the controller's demand thread plans with numpy), without it under 30 ms. The arrays here
    are small: one thread loses nothing. Return how many libraries were set.
    """
    with open('/proc/self/maps') as f:
        paths = {line.split()[-1] for line in f if 'openblas' in line.lower() and '.so' in line}
    done = 0
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        setter = next((getattr(lib, n) for n in BLAS_SET_THREADS if hasattr(lib, n)), None)
        if setter is not None:
            setter(1)
            done += 1
    return done


def run_at_priority(priority: int) -> tuple[bool, str]:
    """
    Run the calling thread at SCHED_FIFO ``priority`` (1..99), the process's others just below.

    Return ``(True, what was done)`` or ``(False, why not)``; priority 0 (or less) changes
    nothing and returns ``(False, 'off')``.
    """
    if isinstance(priority, bool) or not isinstance(priority, int):
        return False, f'priority must be an int in 0..{MAX_PRIORITY}, got {priority!r}'
    if priority <= 0:
        return False, 'off'
    priority = min(priority, MAX_PRIORITY)
    below = max(MIN_PRIORITY, priority - 1)
    me = threading.get_native_id()
    others = [int(t) for t in os.listdir('/proc/self/task') if int(t) != me]
    policy = os.SCHED_FIFO | getattr(os, 'SCHED_RESET_ON_FORK', 0)
    try:
        os.sched_setscheduler(me, policy, os.sched_param(priority))
        for tid in others:
            try:
                os.sched_setscheduler(tid, policy, os.sched_param(below))
            except ProcessLookupError:      # a thread that ended meanwhile
                pass
    except (OSError, AttributeError) as err:
        return False, (f'real-time scheduling refused ({err}); the thread runs at normal '
                       'priority (allow it with an rtprio limit in /etc/security/limits.conf or '
                       'CAP_SYS_NICE)')
    blas = blas_on_one_thread()
    return True, (f'SCHED_FIFO priority {priority}, the {len(others)} other threads of the '
                  f'process at {below}' + (', OpenBLAS on one thread' if blas else ''))


def raise_this_thread(priority: int, log: Any, thread: str, parameter: str) -> bool:
    """
    ``run_at_priority(priority)`` for a node's timed ``thread``, said once on ``log``.

    ``log`` is the node's logger (``info``, ``warning``); the success names the ``thread``, a
    refusal the ``parameter`` and why. Priority 0 (or less) does nothing and says nothing.
    Return whether the thread now runs at real-time priority.
    """
    if priority <= 0:
        return False
    ok, message = run_at_priority(priority)
    if ok:
        log.info(f'{thread} thread at {message}')
    else:
        log.warning(f'{parameter} {priority}: {message}')
    return ok


def run_normal() -> None:
    """Run the calling thread at normal scheduling again (always allowed); the others stay."""
    policy = os.SCHED_OTHER | getattr(os, 'SCHED_RESET_ON_FORK', 0)
    os.sched_setscheduler(threading.get_native_id(), policy, os.sched_param(0))


def scheduling_of_thread() -> tuple[str, int]:
    """Return the calling thread's scheduling policy ('fifo', 'other', ...) and priority."""
    me = threading.get_native_id()
    policy = os.sched_getscheduler(me) & ~getattr(os, 'SCHED_RESET_ON_FORK', 0)
    names = {os.SCHED_FIFO: 'fifo', os.SCHED_OTHER: 'other', os.SCHED_RR: 'rr'}
    return names.get(policy, str(policy)), os.sched_getparam(me).sched_priority


def steady_interpreter(switch_interval: float = SWITCH_INTERVAL) -> Callable[[], None]:
    """
    Set the switch interval and freeze what is loaded out of the collector; return the undo.

    The undo puts the switch interval back and unfreezes (a test's process goes on after).
    """
    previous = sys.getswitchinterval()
    sys.setswitchinterval(switch_interval)
    gc.collect()
    gc.freeze()

    def undo() -> None:
        gc.unfreeze()
        sys.setswitchinterval(previous)
    return undo
