"""
CPU of the three nodes at rest and while moving, with the controller's tick and the bridge's pace.

Measured over 30 s after start-up with nothing moving. Goal: at most 10 % of a core for the
three together at idle, the controller's tick and the bridge's real-time factor unchanged; the
same figures while moving (bench/HISTORY.md has the measurements).

The sim bridge, the controller and the planner start as processes (their config files, in a
namespace of their own). Once the controller is idle and the planner has reported, the start-up
settles for ``SETTLE`` s, then per phase:

- ``rest``: nothing sent;
- ``moving``: motions back and forth on /joint_demands (the next when the last has ended), the
  controller at its default profile;

each with two windows one after the other. The CPU window (``WINDOW`` s): per node, utime +
stime from /proc/<pid>/stat (all its threads) over the window, in % of one core; meanwhile this
process reads only the status topics (5 Hz), so that no reader of its own adds to the nodes'
work. The timing window (``TIMING`` s): this process also reads /JointJog and /joint_states:

- the controller's tick: the period between consecutive /JointJog header stamps (the tick's
  start on the node clock): mean rate, and the period error |period - 1 / rate| p50, p99, max;
- the bridge's real-time factor: sim time over the bridge's monotonic wall time between the
  first and the last of its ~/status reports (once a second) in the window;
- the rate of /joint_states by their stamps (the bridge publishes at ``rest_publish_rate``
  while the arm rests, at ``publish_rate`` while it moves).

The machine may be shared: the load average is printed and stored with the figures. Run:
``./run.sh bench idle`` or ``./run.sh exec python -m bench.bench_idle [--quick] [--repeat N]``
(``--quick``: shorter windows). Writes bench/results/idle.json.
"""

import argparse
import json
import os
import sys
import tempfile
import time

from bench.output import write_json
from mover6_control.nodes.runtime import local_dds
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, 'test'))
NODES = ('sim_bridge', 'controller', 'planner')
SETTLE = 5.0                 # [s] after the stack is up, before the first window
WINDOW = 30.0                # [s] CPU window (the issue's 30 s)
TIMING = 10.0                # [s] tick and real-time-factor window
QUICK = (10.0, 5.0)          # --quick: CPU and timing windows
RATE = 100.0                 # [Hz] the controller's rate (config/controller.yaml)
MOTIONS = np.array([[0.5, -0.4, 0.3, 0.4, -0.3, 0.6], [-0.4, 0.3, -0.3, -0.4, 0.4, -0.5]])
GOAL = 0.10                  # [fraction of one core] the three nodes together at rest
CLK_TCK = os.sysconf('SC_CLK_TCK')


def cpu_seconds(pid):
    """Return the user + system CPU time [s] of process ``pid`` so far (all its threads)."""
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK   # utime, stime (fields 14, 15)


class Probe:
    """The bench's own node: status readers always, /JointJog and /joint_states on request."""

    def __init__(self, namespace):
        """Create the node in its own context, with the status readers and the demand writer."""
        from diagnostic_msgs.msg import DiagnosticStatus
        from mover6_control.nodes.messages import conversions, demand_messages
        from mover6_control.nodes.controller.node import STATUS_QOS
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import Float32MultiArray

        self.rclpy, self.demand_messages = rclpy, demand_messages
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('bench_idle', namespace=namespace, context=self.context)
        self.controller, self.planner, self.bridge = [], [], []
        self.node.create_subscription(
            DiagnosticStatus, 'controller/status',
            lambda m: self.controller.append(conversions.status_values(m)), STATUS_QOS)
        self.node.create_subscription(
            DiagnosticStatus, 'planner/status',
            lambda m: self.planner.append(conversions.status_values(m)), STATUS_QOS)
        self.node.create_subscription(
            DiagnosticStatus, 'sim_bridge/status',
            lambda m: self.bridge.append(conversions.status_values(m)), STATUS_QOS)
        self.demand_pub = self.node.create_publisher(Float32MultiArray, 'joint_demands', 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.jog_stamps, self.state_stamps, self.timing_subs = [], [], []
        self.sent = 0
        self.waiting_for = None        # motion id of the demand sent last, until it ends
        self.results = []

    def state(self):
        """Return the controller's latest state, '' before its first status."""
        return self.controller[-1].get('state', '') if self.controller else ''

    def spin_until(self, predicate, timeout):
        """Spin the probe until ``predicate()`` holds or ``timeout`` [s] passed; return it."""
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        return predicate()

    def spin_for(self, seconds, moving):
        """Spin for ``seconds``; with ``moving``, send the next motion whenever the last ended."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
            if moving:
                self.drive()

    def drive(self):
        """Send the next motion once the last has ended (idle or fault with its motion id)."""
        status = self.controller[-1]
        motion_id = int(status.get('motion_id', 0))
        if self.waiting_for is not None:
            if motion_id == self.waiting_for and status.get('state') in ('idle', 'fault'):
                self.results.append(status.get('result', '?'))
                self.waiting_for = None
            elif 'rejected' in status.get('result', ''):
                self.results.append('rejected')
                self.waiting_for = None
        if self.waiting_for is None and status.get('state') == 'idle':
            demand = self.demand_messages.make_demands(MOTIONS[self.sent % 2][None])
            self.demand_pub.publish(demand)
            self.sent += 1
            self.waiting_for = motion_id + 1

    def start_timing(self):
        """Read /JointJog and /joint_states (their header stamps) from now on."""
        from control_msgs.msg import JointJog
        from sensor_msgs.msg import JointState

        def stamp(msg):
            return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.jog_stamps.clear()
        self.state_stamps.clear()
        self.bridge.clear()
        self.timing_subs = [
            self.node.create_subscription(JointJog, 'JointJog',
                                          lambda m: self.jog_stamps.append(stamp(m)), 100),
            self.node.create_subscription(JointState, 'joint_states',
                                          lambda m: self.state_stamps.append(stamp(m)), 100)]

    def stop_timing(self):
        """Stop reading /JointJog and /joint_states."""
        for sub in self.timing_subs:
            self.node.destroy_subscription(sub)
        self.timing_subs = []

    def close(self):
        """Destroy the node and its context."""
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def timing_figures(jog_stamps, state_stamps, bridge_statuses):
    """Return the tick figures (/JointJog stamps), the real-time factor, the states' rate."""
    jog = np.sort(np.array(jog_stamps))
    periods = np.diff(jog)
    err = np.abs(periods - 1.0 / RATE) * 1e3
    states = np.array(state_stamps)
    span = states[-1] - states[0] if len(states) > 1 else float('nan')
    rtf = float('nan')
    if len(bridge_statuses) > 1:
        first, last = bridge_statuses[0], bridge_statuses[-1]
        rtf = ((float(last['sim_time']) - float(first['sim_time']))
               / (float(last['wall_time']) - float(first['wall_time'])))
    return {'ticks': int(len(jog)),
            'tick_rate_hz': float(len(periods) / (jog[-1] - jog[0])),
            'period_error_p50_ms': float(np.median(err)),
            'period_error_p99_ms': float(np.percentile(err, 99)),
            'period_error_max_ms': float(np.max(err)),
            'joint_states': int(len(states)),
            'joint_states_rate_hz': float((len(states) - 1) / span),
            'bridge_reports': len(bridge_statuses),
            'real_time_factor': rtf}


def run_stack(window, timing, log_dir):
    """Start the three nodes, measure rest then moving; return the figures per phase."""
    from ros_testing import NodeProcess

    namespace = f'bench_idle_{os.getpid()}'
    ns_args = ('-r', f'__ns:=/{namespace}')
    os.makedirs(log_dir, exist_ok=True)
    nodes = {}
    probe = None
    try:
        for name in NODES:
            nodes[name] = NodeProcess(name, log_dir, ros_args=ns_args)
        probe = Probe(namespace)
        if not probe.spin_until(lambda: probe.state() == 'idle' and probe.planner
                                and probe.demand_pub.get_subscription_count() > 0, 60.0):
            raise RuntimeError('the stack did not come up within 60 s:\n'
                               + '\n'.join(n.tail() for n in nodes.values()))
        probe.spin_for(SETTLE, moving=False)
        phases = {}
        for phase in ('rest', 'moving'):
            moving = phase == 'moving'
            if moving:
                probe.drive()
                probe.spin_for(1.0, moving)          # the first motion under way
            before = {name: cpu_seconds(n.pid) for name, n in nodes.items()}
            t0 = time.monotonic()
            probe.spin_for(window, moving)
            seconds = time.monotonic() - t0
            after = {name: cpu_seconds(n.pid) for name, n in nodes.items()}
            cpu = {name: 100.0 * (after[name] - before[name]) / seconds for name in NODES}
            probe.start_timing()
            probe.spin_for(timing, moving)
            probe.stop_timing()
            row = {'cpu_percent': cpu, 'cpu_percent_total': sum(cpu.values()),
                   'cpu_window_s': seconds, 'load_average': list(os.getloadavg())}
            row.update(timing_figures(probe.jog_stamps, probe.state_stamps, probe.bridge))
            if moving:
                row['motions_sent'] = probe.sent
                row['motions_arrived'] = probe.results.count('arrived')
                row['motions_not_arrived'] = len(probe.results) - row['motions_arrived']
            phases[phase] = row
        alive = {name: n.alive() for name, n in nodes.items()}
    finally:
        if probe is not None:
            probe.close()
        for n in nodes.values():
            n.stop()
    phases['alive_to_the_end'] = alive
    return phases


def main(argv=None):
    """Run the stack ``--repeat`` times; print the table and write bench/results/idle.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help=f'windows of {QUICK[0]:g} s and {QUICK[1]:g} s')
    parser.add_argument('--repeat', type=int, default=1, help='fresh stacks, one after another')
    args = parser.parse_args(argv)
    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    window, timing = QUICK if args.quick else (WINDOW, TIMING)
    log_dir = tempfile.mkdtemp(prefix='bench_idle_')
    load = os.getloadavg()
    print(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs '
          '(other processes on the machine disturb every figure below); logs in ' + log_dir)
    results = {'quick': args.quick, 'cpu_window_s': window, 'timing_window_s': timing,
               'cpus': os.cpu_count(), 'load_average_at_start': list(load), 'runs': []}
    for i in range(args.repeat):
        run = run_stack(window, timing, os.path.join(log_dir, f'run{i + 1}'))
        results['runs'].append(run)
        print(json.dumps(run), flush=True)
    print(f'\nCPU [% of one core] over {window:g} s per phase; tick and real-time factor over '
          f'{timing:g} s after it. Goal at rest: the three together <= {GOAL * 100:g} %')
    print(f'{"run":>3} {"phase":>7} {"sim_bridge":>10} {"controller":>10} {"planner":>8} '
          f'{"total":>6} {"tick [Hz]":>9} {"err p50":>8} {"err p99":>8} {"err max":>8} '
          f'{"RTF":>6} {"states [Hz]":>11} {"motions":>8} {"load 1 min":>10}')
    for i, run in enumerate(results['runs']):
        for phase in ('rest', 'moving'):
            row = run[phase]
            c = row['cpu_percent']
            motions = (f'{row["motions_arrived"]}/{row["motions_sent"]}' if phase == 'moving'
                       else '')
            print(f'{i + 1:>3} {phase:>7} {c["sim_bridge"]:10.1f} {c["controller"]:10.1f} '
                  f'{c["planner"]:8.1f} {row["cpu_percent_total"]:6.1f} '
                  f'{row["tick_rate_hz"]:9.2f} {row["period_error_p50_ms"]:8.3f} '
                  f'{row["period_error_p99_ms"]:8.3f} {row["period_error_max_ms"]:8.3f} '
                  f'{row["real_time_factor"]:6.3f} {row["joint_states_rate_hz"]:11.1f} '
                  f'{motions:>8} {row["load_average"][0]:10.2f}')
    print('(period error |period - 10 ms| in ms, from the /JointJog stamps; RTF from the '
          'sim bridge ~/status, sim time over its wall time; states: /joint_states by stamps)')
    write_json('idle', results)
    dead = [name for run in results['runs'] for name, ok in run['alive_to_the_end'].items()
            if not ok]
    return 1 if dead else 0


if __name__ == '__main__':
    sys.exit(main())
