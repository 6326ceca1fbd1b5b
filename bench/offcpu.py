"""
Where the threads of a process wait: the longest off-CPU intervals, each with its stack.

A stalled tick shows in ``MOVER6_TICK_WATCHDOG``'s Python stacks only as "inside
``Publisher.publish``"; what that call waits for, and which thread holds it up, is below Python.
This records every context switch of chosen threads of a running process with ``perf`` (the
``sched:sched_switch`` tracepoint, user stacks unwound with DWARF), then prints the longest
intervals between a thread leaving the CPU and its next switch, with the stack at which it left:
the call that blocked (a mutex, a sleep, a socket wait).

Use (perf must be allowed to trace the process: root, or ``perf_event_paranoid`` <= 1)::

    python -m bench.offcpu record PID OUT.data [--threads dds.] [--seconds 60]
    python -m bench.offcpu report OUT.data [--top 8] [--min-ms 20]

``bench_churn --offcpu`` records the controller's Fast DDS threads during its run. Idle waits
(a receive thread in ``recvfrom`` or ``wait_pop``, the event thread's timed wait, the
shared-memory watchdog, the asynchronous writer thread waiting for work) are left out of the
report unless ``--all``.
"""

import argparse
import os
import re
import subprocess
import sys

# Frames of waits that are a thread's normal idle state, not a stall.
IDLE_FRAMES = ('recvfrom', 'Port::wait_pop', 'SharedMemWatchdog', 'event_service',
               'ResourceEvent::run', 'select_poll', 'epoll_wait', 'FlowControllerImpl')
HEADER = re.compile(r'\s*(\S.*?)\s+(\d+)\s+([\d.]+):')


def thread_ids(pid, prefix):
    """Return the ids of the threads of ``pid`` whose name starts with ``prefix``."""
    tids = []
    for tid in sorted(os.listdir(f'/proc/{pid}/task'), key=int):
        try:
            with open(f'/proc/{pid}/task/{tid}/comm') as f:
                name = f.read().strip()
        except OSError:          # the thread ended meanwhile
            continue
        if name.startswith(prefix):
            tids.append(tid)
    return tids


def start_recording(pid, out_path, prefix='dds.', log=None):
    """
    Start ``perf record`` on the threads of ``pid`` named ``prefix``*; return the Popen.

    ``prefix`` '': every thread of the process (the Python threads too), threads started later
    included.
    """
    if prefix:
        tids = thread_ids(pid, prefix)
        if not tids:
            raise RuntimeError(f'no thread of {pid} is named {prefix}*')
        target = ['-t', ','.join(tids)]
    else:
        target = ['-p', str(pid)]
    return subprocess.Popen(
        ['perf', 'record', '-q', '-e', 'sched:sched_switch', '--call-graph', 'dwarf,16384',
         *target, '-o', out_path],
        stdout=log or subprocess.DEVNULL, stderr=subprocess.STDOUT)


def stop_recording(proc):
    """Stop a recording started by ``start_recording`` (SIGINT: perf writes its file)."""
    if proc.poll() is None:
        proc.send_signal(2)
    try:
        proc.wait(60.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5.0)


def switches(perf_data):
    """
    Yield ``(tid, time [s], thread name, state, stack)`` per switch recorded in ``perf_data``.

    ``state`` is the thread's state as it left the CPU: ``S`` or ``D`` waiting, ``R`` preempted
    (ready to run, waiting for a CPU).
    """
    text = subprocess.run(
        ['perf', 'script', '-i', perf_data, '-F', 'comm,tid,time,trace,ip,sym,dso'],
        capture_output=True, text=True, check=True).stdout
    for block in text.split('\n\n'):
        lines = block.strip().splitlines()
        match = HEADER.match(lines[0]) if lines else None
        if match:
            state = re.search(r'prev_state=(\S+)', lines[0])
            yield (int(match.group(2)), float(match.group(3)), match.group(1),
                   state.group(1) if state else '?', lines[1:])


def waits(perf_data, include_idle=False):
    """
    Return the off-CPU intervals, longest first: ``(duration [s], tid, name, state, t0, stack)``.

    The interval runs from a switch away from a thread to that thread's next switch: an upper
    bound of the wait (it includes the time it then ran, normally microseconds; an event perf
    lost merges two intervals: ``perf.log`` says when it lost any).
    """
    by_thread = {}
    for tid, t, name, state, stack in switches(perf_data):
        by_thread.setdefault(tid, []).append((t, name, state, stack))
    found = []
    for tid, events in by_thread.items():
        for (t0, name, state, stack), (t1, *_) in zip(events, events[1:]):
            if include_idle or not any(f in line for line in stack for f in IDLE_FRAMES):
                found.append((t1 - t0, tid, name, state, t0, stack))
    found.sort(key=lambda w: -w[0])
    return found


def short(frame):
    """Return a stack line without its address, library path and template arguments."""
    frame = re.sub(r'^\s*[0-9a-f]+ ', '', frame.strip())
    frame = re.sub(r' \((/|\[).*\)$', '', frame)
    return re.sub(r'<.*', '<...>', frame)[:150]


def report(perf_data, top=8, min_ms=20.0, include_idle=False, out=sys.stdout):
    """Print the ``top`` longest waits of at least ``min_ms`` [ms] with their user stacks."""
    found = [w for w in waits(perf_data, include_idle) if w[0] * 1e3 >= min_ms]
    print(f'{len(found)} waits of {min_ms:g} ms or more in {perf_data}', file=out)
    for duration, tid, name, state, t0, stack in found[:top]:
        how = 'preempted, waiting for a CPU' if state.startswith('R') else f'state {state}'
        print(f'\n{duration * 1e3:.1f} ms  thread {name} ({tid}, {how})  from t={t0:.3f} s',
              file=out)
        user = [s for s in stack if 'kernel.kallsyms' not in s]
        for frame in user[:24]:
            print('    ' + short(frame), file=out)
    return found


def main(argv=None):
    """Record or report, as the command line says."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = parser.add_subparsers(dest='command', required=True)
    rec = sub.add_parser('record', help='record the context switches of a running process')
    rec.add_argument('pid', type=int)
    rec.add_argument('out')
    rec.add_argument('--threads', default='dds.', help='thread name prefix (default dds.)')
    rec.add_argument('--seconds', type=float, default=60.0)
    rep = sub.add_parser('report', help='print the longest waits of a recording')
    rep.add_argument('data')
    rep.add_argument('--top', type=int, default=8)
    rep.add_argument('--min-ms', type=float, default=20.0)
    rep.add_argument('--all', action='store_true', help='include idle waits')
    args = parser.parse_args(argv)
    if args.command == 'record':
        proc = start_recording(args.pid, args.out, args.threads)
        try:
            proc.wait(args.seconds)
        except subprocess.TimeoutExpired:
            pass
        stop_recording(proc)
    else:
        report(args.data, args.top, args.min_ms, args.all)
    return 0


if __name__ == '__main__':
    sys.exit(main())
