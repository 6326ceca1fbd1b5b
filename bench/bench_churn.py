"""
The controller's tick while the ROS graph churns.

"Motions while 40 processes join and leave the graph; the largest tick gap and the p99 period
error, before and after. Goal: largest gap under 30 ms, no stale-command halt at the bridge, no
aborted motion."

Per variant, the sim bridge (real time) and the controller (100 Hz, continuous profile) start as
processes in their own namespace; this process sends motions back and forth on /joint_demands
(the next when the last has ended) while ``CHURN`` short-lived processes join the graph, a few
at a time: each is a small rclpy script that subscribes to /controller/status (transient local,
as ``ros2 topic echo`` does), waits for one message and exits. Figures:

- largest tick gap [ms] and the period error |period - 10 ms| (p50, p99, max) [ms], from the
  monotonic time at the start of every tick, recorded inside the controller process (its
  ``on_tick`` wrapped, as bench_controller does); also the controller's own ``max_tick_gap``;
- largest gap between /JointJog messages as this process received them [ms] (a receiver on a
  loaded machine adds its own delays);
- the bridge's "joints halted" lines (a /JointJog older than its 0.2 s ``command_timeout``);
- motions sent, arrived, and ended otherwise (aborted, fault, stopped).

The variants run one after the other in the same run (``--repeat N``: N times, alternately),
each with a fresh stack; the environment applies to the controller and the bridge. The default
rows: ``local``, the product's local configuration as it ships (UDP on 127.0.0.1, the tick and
the physics thread at SCHED_FIFO 50 where allowed), and ``localhost``, ROS's LOCALHOST
discovery (Fast DDS as rmw_fastrtps sets it up under it, both threads at normal scheduling).
Others (``VARIANTS``): ``local_prio0``, ``localhost_prio50`` (one of the two changes each) and
``async`` (``RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS``). The
machine is shared: the load average is printed and stored. Halts are counted from the bridge's
log between the first motion and the end of the last (the controller stops before the bridge,
so the bridge halts once more at teardown: reported apart).

What the stalls are, measured (``--offcpu``: perf records where the controller's Fast DDS
threads wait, ``bench/offcpu.py`` prints the longest waits with their stacks; the tick thread's
own stack comes from ``MOVER6_TICK_WATCHDOG``):

- the tick thread sits in ``Publisher.publish`` (JointJog) for ~333 ms. rclpy keeps the
  interpreter lock during ``rcl_publish``, so every Python thread of the node stops with it;
- the publish waits for the participant's send lock (Fast DDS 2.14 ``RTPSParticipantImpl::
  sendSync`` holds one mutex per participant across the send on every transport). Meanwhile the
  receive thread that handles discovery holds it: a churn process's reader was discovered,
  ``StatefulWriter::matched_reader_add`` sends to it at once, and the shared-memory transport
  opens the new process's port: ``SharedMemGlobal::open_port_internal`` polls the port's health
  check (``nanosleep``) for 333 ms. The shared-memory receive threads wait on the PDP mutex
  meanwhile, so /joint_states stop arriving too (``state_timeout`` 0.25 s: the controller faults).
  333 ms is a third of the default ``healthy_check_timeout_ms`` (1000): the health check of a
  fresh, healthy port waits for the port's watchdog round (eProsima/Fast-DDS#6535, open).
  Every reliable writer matched by a new process takes that path; rmw's own
  ``ros_discovery_info`` writer is matched by every new ROS process, so no QoS of ours avoids it;
- asynchronous publication moves the JointJog write to Fast DDS's thread, which then waits for
  the same lock (and the status writer is the one being matched): the JointJog still arrives
  ~360 ms late;
- the shared-memory transport cannot be switched off the usual ways while
  ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is ``LOCALHOST``: rmw_fastrtps (Jazzy) then sets the
  participant's transports itself (shared memory plus UDPv4), so neither
  ``FASTDDS_BUILTIN_TRANSPORTS`` nor an XML transport setting has any effect (a ``udp_only``
  variant that was here measured the default configuration twice; ``controller_dds_threads``
  in the JSON lists the threads the controller ran). A GUID prefix of another host (which rmw
  does take from the XML profile) does not help either: Fast DDS picks shared memory per remote
  locator (``SHMLocator::is_shm_and_from_this_host``, the host id inside the locator), and the
  controller still opened a joining process's port. Left: a Fast DDS with
  eProsima/Fast-DDS#6535 fixed, or the package's local configuration (its loopback-only Fast DDS
  profile, which nodes refuse to start without: UDP on 127.0.0.1, no shared memory), the
  ``local`` rows;
- the shorter gaps (20-150 ms, ``ticks_over_30ms``) are the process waiting for a CPU on a
  loaded machine (two cores, load 4-11 during these runs; the watchdog then finds the tick
  thread anywhere in its Python code). ``tick_priority`` alone narrowed them (period error p50
  and p99) but could not remove them: the real-time tick thread still needs the interpreter
  lock, which a preempted normal-priority thread of the node may hold (so the node's other
  threads now run one below the tick). The stall warning is logged from the
  tick thread (rclpy's throttled logger inspects the caller's source file, and /rosout is a DDS
  write): in one run the tick that logged a 72 ms gap began a 360 ms gap itself, its log line
  stamped 350 ms after the tick started.

Rows other than ``localhost`` start DDS with another configuration: run the benchmark inside a
private network namespace on a shared machine. Run: ``./run.sh bench churn`` or
``./run.sh exec python -m bench.bench_churn [--quick]
[--churn N] [--variant NAME] [--repeat N] [--offcpu]`` (``--quick``: 16 churn processes instead of
40).
Writes
bench/results/churn.json.
"""

import argparse
import faulthandler
import json
import os
import re
import subprocess
import sys
import tempfile
import time

from bench import offcpu as offcpu_tool
from bench.output import write_json
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, 'test'))
RATE = 100.0
CHURN = 40
CHURN_QUICK = 16
AT_ONCE = 4                  # churn processes alive at the same time
CHURN_TIMEOUT = 30.0         # [s] a churn process that saw no status by then is killed
EXIT_HANG = 5.0              # [s] a churn process still exiting this long after its line dumps
SAW = re.compile(r'churn (\d+): saw a status')   # lines of two processes may run together
MOTIONS = np.array([[0.5, -0.4, 0.3, 0.4, -0.3, 0.6], [-0.4, 0.3, -0.3, -0.4, 0.4, -0.5]])
HALT_LINE = '/JointJog command stale: joints halted'
LOG_STAMP = re.compile(r'^\[\w+\] \[(\d+\.\d+)\]')   # a ROS log line: [LEVEL] [wall time]
# The rows measured side by side: (name, DDS configuration, environment, controller parameters,
# sim bridge parameters).
# Every process of a row, the churn processes and this benchmark's own included, runs in the
# row's DDS configuration: ``localhost`` is ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
# (rmw_fastrtps adds shared memory), ``local`` the package's local configuration
# (``nodes.runtime.local_dds``: UDP on 127.0.0.1 only, no shared memory). Parameters not
# given are the shipped files' (config/*.yaml): ``local`` is the product as it ships (the tick and
# the physics thread at SCHED_FIFO 50 where allowed), ``localhost`` ROS's LOCALHOST discovery
# (both at normal scheduling, priority 0); ``local_prio0`` and ``localhost_prio50`` swap one of
# the two changes. ``async`` was tried against the 333 ms stall under LOCALHOST and removed none
# of it (module doc); it stays so that it can be measured again.
NORMAL = ({'tick_priority': 0}, {'physics_priority': 0})
VARIANTS = (('localhost', 'localhost', {}, *NORMAL),
            ('local', 'local', {}, {}, {}),
            ('local_prio0', 'local', {}, *NORMAL),
            ('localhost_prio50', 'localhost', {}, {}, {}),
            ('async', 'localhost', {'RMW_FASTRTPS_PUBLICATION_MODE': 'ASYNCHRONOUS'}, *NORMAL))
DEFAULT_VARIANTS = ('localhost', 'local')
MOTION_LIMIT = 60.0          # [s] a motion whose end no status showed by then did not arrive
STALL = 0.2                  # [s] a tick gap this long is a stall (the driver halts at 0.2 s)


def echo_main(topic):
    """Subscribe to ``topic`` (transient local), wait for one status, exit: ros2 topic echo."""
    from diagnostic_msgs.msg import DiagnosticStatus
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile

    rclpy.init()
    node = rclpy.create_node(f'churn_{os.getpid()}')
    got = []
    node.create_subscription(DiagnosticStatus, topic, got.append,
                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    deadline = time.monotonic() + CHURN_TIMEOUT
    while not got and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    seen = 'saw a status' if got else f'no status within {CHURN_TIMEOUT:g} s'
    print(f'churn {os.getpid()}: {seen}', flush=True)
    # A process still leaving the graph EXIT_HANG s later says where it waits (one did, once in
    # some thirty runs: it had seen its status, then was killed before it exited).
    faulthandler.dump_traceback_later(EXIT_HANG, exit=False)
    node.destroy_node()
    rclpy.shutdown()
    faulthandler.cancel_dump_traceback_later()
    return 0 if got else 1


class Churn:
    """Start ``total`` echo processes, ``AT_ONCE`` alive at a time; stop stragglers by pid."""

    def __init__(self, topic, total, log_dir):
        self.topic, self.left, self.log_dir = topic, total, log_dir
        self.running, self.exit_codes, self.pids, self.killed = [], [], [], []

    def saw_status(self):
        """Return the pids of the processes that printed that they saw a status."""
        with open(os.path.join(self.log_dir, 'churn.log')) as log:
            printed = {int(pid) for pid in SAW.findall(log.read())}
        return [pid for pid in self.pids if pid in printed]

    def step(self):
        """Reap finished processes and start new ones; return True while any is left."""
        for proc, started in list(self.running):
            if proc.poll() is not None:
                self.exit_codes.append(proc.returncode)
                self.running.remove((proc, started))
            elif time.monotonic() - started > CHURN_TIMEOUT + 10.0:
                proc.kill()
                proc.wait(5.0)
                self.exit_codes.append('killed')
                self.killed.append(proc.pid)
                self.running.remove((proc, started))
        while self.left > 0 and len(self.running) < AT_ONCE:
            self.left -= 1
            with open(os.path.join(self.log_dir, 'churn.log'), 'a') as log:
                proc = subprocess.Popen(
                    [sys.executable, '-m', 'bench.bench_churn', '--echo', self.topic],
                    stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
            self.running.append((proc, time.monotonic()))
            self.pids.append(proc.pid)
        return self.left > 0 or bool(self.running)

    def stop(self):
        """Kill the processes still running, by pid."""
        for proc, _ in self.running:
            proc.kill()
            proc.wait(5.0)
            self.exit_codes.append('killed')
            self.killed.append(proc.pid)
        self.running = []


def dds_threads(pid):
    """Return the sorted names of the Fast DDS threads (``dds.*``) of process ``pid``."""
    names = set()
    for tid in os.listdir(f'/proc/{pid}/task'):
        try:
            with open(f'/proc/{pid}/task/{tid}/comm') as f:
                name = f.read().strip()
        except OSError:
            continue
        if name.startswith('dds.'):
            names.add(name)
    return sorted(names)


def log_lines_between(path, line, wall_t0, wall_t1):
    """Count the lines of ROS log ``path`` containing ``line``: (inside, after) [t0, t1] (wall)."""
    inside = after = 0
    with open(path) as f:
        for text in f:
            if line not in text:
                continue
            stamp = LOG_STAMP.search(text)
            t = float(stamp.group(1)) if stamp else float('inf')
            if wall_t0 <= t <= wall_t1:
                inside += 1
            elif t > wall_t1:
                after += 1
    return inside, after


def logged(path, line):
    """Return whether ``line`` appears in the log file ``path``."""
    with open(path) as f:
        return any(line in text for text in f)


def run_variant(name, env_extra, params, total, log_dir, offcpu=False, bridge_params=None):
    """
    Run the stack with ``env_extra`` for the controller under churn; return the figures.

    ``offcpu``: record where the controller's Fast DDS threads wait (``bench.offcpu``) during the
    motions; the longest waits go to ``offcpu.txt`` in the variant's log directory.
    """
    from control_msgs.msg import JointJog
    from diagnostic_msgs.msg import DiagnosticStatus
    from mover6_control.nodes.messages import conversions, demand_messages
    from mover6_control.nodes.runtime.qos import STATUS_QOS
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from ros_testing import NodeProcess
    from std_msgs.msg import Float32MultiArray

    namespace = f'churn_{name}_{os.getpid()}'
    ns_args = ('-r', f'__ns:=/{namespace}')
    variant_dir = os.path.join(log_dir, name)
    os.makedirs(variant_dir, exist_ok=True)
    probe_path = os.path.join(variant_dir, 'ticks.npy')
    perf_path = os.path.join(variant_dir, 'perf.data')
    perf = None
    saved = {k: os.environ.get(k) for k in env_extra}
    os.environ.update(env_extra)          # the bridge runs as the controller does
    try:
        bridge = NodeProcess('sim_bridge', variant_dir, params=bridge_params, ros_args=ns_args)
    finally:
        for key, value in saved.items():
            if value is None:
                del os.environ[key]
            else:
                os.environ[key] = value
    cmd = [sys.executable, '-m', 'bench.bench_controller', '--probe', probe_path, '--ros-args',
           '--params-file', os.path.join(ROOT, 'config', 'controller.yaml'),
           '-p', f'rate:={RATE}']
    for key, value in params.items():
        cmd += ['-p', f'{key}:={value}']
    cmd += list(ns_args)
    controller_log = open(os.path.join(variant_dir, 'controller.log'), 'w')
    env = dict(os.environ, PYTHONUNBUFFERED='1', **env_extra)
    controller = subprocess.Popen(cmd, stdout=controller_log, stderr=subprocess.STDOUT, cwd=ROOT,
                                  env=env)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('bench_churn', namespace=namespace, context=context)
    jog_times, statuses = [], []
    node.create_subscription(JointJog, 'JointJog', lambda m: jog_times.append(time.monotonic()),
                             100)
    node.create_subscription(DiagnosticStatus, 'controller/status',
                             lambda m: statuses.append(conversions.status_values(m)), STATUS_QOS)
    demand_pub = node.create_publisher(Float32MultiArray, 'joint_demands', 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    churn = Churn(f'/{namespace}/controller/status', total, variant_dir)
    motions = {}          # motion_id -> result
    sent = 0
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not (
                statuses and statuses[-1].get('state') == 'idle' and len(jog_times) > 50
                and demand_pub.get_subscription_count() > 0):
            executor.spin_once(timeout_sec=0.05)
        if not statuses or statuses[-1].get('state') != 'idle':
            raise RuntimeError(f'{name}: the controller did not become idle within 60 s '
                               f'(last status {statuses[-1:]})')
        time.sleep(0.5)
        threads = dds_threads(controller.pid)
        if offcpu:
            perf_log = open(os.path.join(variant_dir, 'perf.log'), 'w')
            perf = offcpu_tool.start_recording(controller.pid, perf_path, prefix='',
                                               log=perf_log)
        t0, wall_t0 = time.monotonic(), time.time()
        waiting_for = None    # the motion id of the demand sent last, until it ends
        sent_at = t0
        # Motions back and forth until the churn is over and the last motion has ended.
        while True:
            churning = churn.step()
            seen = len(statuses)
            executor.spin_once(timeout_sec=0.02)
            status = statuses[-1]
            if waiting_for is not None:
                if any('rejected' in v for v in statuses[seen:]):
                    motions[f'rejected {sent}'] = 'rejected'
                    waiting_for = None
                elif (int(status.get('motion_id', 0)) == waiting_for
                        and status.get('state') in ('idle', 'fault')):
                    motions[waiting_for] = status.get('result', '?')
                    waiting_for = None
                elif (int(status.get('motion_id', 0)) < waiting_for
                      and time.monotonic() - sent_at > 10.0):
                    raise RuntimeError(f'{name}: demand {waiting_for} not taken within 10 s')
                elif time.monotonic() - sent_at > MOTION_LIMIT:
                    # No status said it ended (the statuses stopped reaching this process once,
                    # under LOCALHOST): not arrived, and the row goes on instead of hanging.
                    motions[waiting_for] = 'no end seen'
                    waiting_for = None
            if waiting_for is None:
                if not churning or time.monotonic() - t0 > 600.0:
                    break
                if status.get('state') != 'idle':      # a fault clears with fresh states
                    continue
                demand_pub.publish(demand_messages.make_demands(MOTIONS[sent % 2][None, :]))
                sent += 1
                waiting_for = int(status.get('motion_id', 0)) + 1
                sent_at = time.monotonic()
        t1, wall_t1 = time.monotonic(), time.time()
        last_status = statuses[-1]
    finally:
        churn.stop()
        if perf is not None:
            offcpu_tool.stop_recording(perf)
            perf_log.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if controller.poll() is None:
            controller.send_signal(2)
            try:
                controller.wait(10.0)
            except subprocess.TimeoutExpired:
                controller.kill()
                controller.wait(5.0)
        controller_log.close()
        bridge.stop()
    ticks = np.load(probe_path)
    ticks = ticks[(ticks >= t0) & (ticks <= t1)]
    periods = np.diff(ticks)
    err = np.abs(periods - 1.0 / RATE)
    jog = np.array(jog_times)
    jog = jog[(jog >= t0) & (jog <= t1)]
    halts, halts_after = log_lines_between(bridge.log_path, HALT_LINE, wall_t0, wall_t1)
    stall_lines, _ = log_lines_between(controller_log.name, 'the tick thread stalled', wall_t0,
                                       wall_t1)
    # What the row ran at: the nodes say once whether their timed thread got SCHED_FIFO.
    scheduling = {key: logged(path, line) for key, path, line in (
        ('tick_thread_fifo', controller_log.name, 'tick thread at SCHED_FIFO'),
        ('physics_thread_fifo', bridge.log_path, 'physics thread at SCHED_FIFO'))}
    longest_waits = []
    if perf is not None:
        with open(os.path.join(variant_dir, 'offcpu.txt'), 'w') as f:
            found = offcpu_tool.report(perf_path, top=8, min_ms=20.0, out=f)
        for duration, _, thread, state, _, stack in found[:3]:
            frames = [offcpu_tool.short(s) for s in stack if 'eprosima' in s]
            longest_waits.append({'ms': round(duration * 1e3, 1), 'thread': thread,
                                  'state': state, 'frames': frames[:6]})
    results = list(motions.values())
    saw = churn.saw_status()
    return {'variant': name, 'env': env_extra, 'params': params,
            'bridge_params': bridge_params or {}, 'seconds': t1 - t0,
            'ticks': int(len(ticks)),
            'churn_processes': total,
            'churn_saw_status': len(saw),
            'churn_exit_codes': churn.exit_codes,
            # saw its status, then did not leave the graph by the time it was killed (rclpy's
            # destroy_node / shutdown: the process's own leaving, not the controller's tick)
            'churn_killed_after_seeing': [pid for pid in churn.killed if pid in saw],
            'max_tick_gap_ms': float(np.max(periods) * 1e3),
            'period_error_p50_ms': float(np.median(err) * 1e3),
            'period_error_p99_ms': float(np.percentile(err, 99) * 1e3),
            'period_error_max_ms': float(np.max(err) * 1e3),
            'ticks_over_30ms': int(np.sum(periods > 0.030)),
            f'ticks_over_{STALL * 1e3:.0f}ms': int(np.sum(periods > STALL)),
            'controller_max_tick_gap_ms': float(last_status.get('max_tick_gap', 'nan')) * 1e3,
            'controller_stall_warnings': stall_lines,
            'jointjog_received_max_gap_ms': float(np.max(np.diff(jog)) * 1e3),
            'bridge_halts': halts, 'bridge_halts_at_teardown': halts_after,
            **scheduling, 'controller_dds_threads': threads, 'offcpu_longest_waits': longest_waits,
            'motions_sent': sent,
            'motions_arrived': results.count('arrived'),
            'motions_not_arrived': len(results) - results.count('arrived'),
            'motion_results': results, 'log_dir': variant_dir}


def dds_environment(dds, environ):
    """Return ``environ`` with DDS configuration ``dds`` (``localhost`` or ``local``) only."""
    from mover6_control.nodes.runtime import local_dds
    env = {k: v for k, v in environ.items() if k not in local_dds.USER_DDS_ENV}
    if dds == 'local':
        env.update(local_dds.local_environment())
    else:
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return env


def run_row(name, total, log_dir, offcpu):
    """Run row ``name`` in a process of its own in the row's DDS configuration; return it."""
    _, dds, _, _, _ = next(v for v in VARIANTS if v[0] == name)
    out = os.path.join(log_dir, f'{name}.json')
    cmd = [sys.executable, '-m', 'bench.bench_churn', '--row', name, str(total), log_dir, out]
    if offcpu:
        cmd.append('--offcpu')
    subprocess.run(cmd, env=dds_environment(dds, os.environ), cwd=ROOT, check=True)
    with open(out) as f:
        row = json.load(f)
    row['dds'] = dds
    return row


def row_main(name, total, log_dir, out, offcpu):
    """Run row ``name`` in this process (its DDS configuration set by ``run_row``)."""
    _, _, env_extra, params, bridge_params = next(v for v in VARIANTS if v[0] == name)
    row = run_variant(name, env_extra, params, int(total), log_dir, offcpu, bridge_params)
    with open(out, 'w') as f:
        json.dump(row, f)
    return 0


def main(argv=None):
    """Run the variants; print the table and write bench/results/churn.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help=f'{CHURN_QUICK} churn processes instead of {CHURN}')
    parser.add_argument('--churn', type=int, help='this many churn processes')
    parser.add_argument('--variant', action='append', choices=[v[0] for v in VARIANTS],
                        help=f'run only this variant (may repeat; default: '
                        f'{" ".join(DEFAULT_VARIANTS)})')
    parser.add_argument('--repeat', type=int, default=1,
                        help='run the variants this many times, alternately')
    parser.add_argument('--offcpu', action='store_true',
                        help="record where the controller's DDS threads wait (perf; see "
                        'bench/offcpu.py)')
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_DOMAIN_ID', '33')
    total = args.churn or (CHURN_QUICK if args.quick else CHURN)
    log_dir = tempfile.mkdtemp(prefix='bench_churn_')
    load = os.getloadavg()
    results = {'quick': args.quick, 'repeat': args.repeat, 'rate_hz': RATE, 'cpus': os.cpu_count(),
               'load_average_at_start': list(load), 'variants': []}
    print(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs '
          '(other processes on the machine disturb every figure below); logs in ' + log_dir)
    chosen = args.variant or DEFAULT_VARIANTS
    runs = [(rep, v[0]) for rep in range(args.repeat) for v in VARIANTS if v[0] in chosen]
    for repetition, name in runs:
        row_dir = os.path.join(log_dir, f'run{repetition + 1}')
        os.makedirs(row_dir, exist_ok=True)
        row = run_row(name, total, row_dir, args.offcpu)
        row['repetition'] = repetition + 1
        row['load_average_after'] = list(os.getloadavg())
        results['variants'].append(row)
        print(f'{name}: {json.dumps({k: v for k, v in row.items() if k != "motion_results"})}',
              flush=True)
    print(f'\n{total} processes join and leave the graph (each echoes /controller/status once) '
          f'during motions; controller at {RATE:g} Hz. Goal: largest gap < 30 ms, no halt, '
          'no aborted motion')
    stall_key = f'ticks_over_{STALL * 1e3:.0f}ms'
    print(f'{"variant":>10} {"run":>3} {"ticks":>6} {"max gap [ms]":>13} {"err p50 [ms]":>13} '
          f'{"err p99 [ms]":>13} {">30 ms":>7} {f">{STALL * 1e3:.0f} ms":>7} '
          f'{"jog rx max gap [ms]":>20} {"halts":>6} '
          f'{"motions ok/sent":>16} {"load 1 min":>11} {"FIFO tick/physics":>18}')
    for row in results['variants']:
        print(f'{row["variant"]:>10} {row["repetition"]:3d} {row["ticks"]:6d} '
              f'{row["max_tick_gap_ms"]:13.1f} '
              f'{row["period_error_p50_ms"]:13.3f} {row["period_error_p99_ms"]:13.3f} '
              f'{row["ticks_over_30ms"]:7d} {row[stall_key]:7d} '
              f'{row["jointjog_received_max_gap_ms"]:20.1f} '
              f'{row["bridge_halts"]:6d} '
              f'{row["motions_arrived"]:>7d}/{row["motions_sent"]:<8d} '
              f'{row["load_average_after"][0]:11.2f} '
              f'{"yes" if row["tick_thread_fifo"] else "no":>14}/'
              f'{"yes" if row["physics_thread_fifo"] else "no":<3}')
    write_json('churn', results)


if __name__ == '__main__':
    if sys.argv[1:2] == ['--echo']:
        sys.exit(echo_main(sys.argv[2]))
    elif sys.argv[1:2] == ['--row']:
        sys.exit(row_main(*sys.argv[2:6], offcpu='--offcpu' in sys.argv[6:]))
    else:
        main()
