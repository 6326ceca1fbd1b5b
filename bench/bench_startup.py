"""
The launch as a user starts it, to a stack that takes goals, and the first goal after that.

This process starts its goal client first (a ``GoalClient`` in a namespace of its own, spinning),
then ``scripts/launch.sh --namespace NS`` exactly as ``./run.sh launch`` runs it (the default
stack of ``mover6_control/stack.py``: the simulated arm, the controller, the planner and the
helpers; the launchers' loopback-only DDS). Times from the command's start [s]:

- ``joint_states``: the first /joint_states heard;
- ``controller``: the first /controller/status past ``waiting_for_states``;
- ``planner``: the first /planner/status that says ``ready``;
- ``ready``: all of the readiness checks of the goal client hold at once (``Readiness``: the
  above, a subscriber on /pose_goal, the planner and the controller on /joint_demands).

Then one pose goal (the planner bench's first pose) is published at once: ``first_goal_planned``
[ms] is the publish to its /joint_demands arriving here (the planner's plan), ``first_goal_exec``
[ms] the publish to the controller's status saying ``executing``; ``cpu_s_at_ready``: the CPU
seconds each process of the launch had used at ready (``launch.sh`` with the short commands it
ran before the nodes). The stack is stopped (SIGINT to
launch.sh, which stops its nodes) before the next run.

Run: ``./run.sh bench startup [--repeat N]`` (default 5 runs) or ``./run.sh exec python -m
bench.bench_startup [--root DIR]`` (``--root``: the checkout whose scripts/launch.sh runs, for a
comparison with another build's environment); writes bench/results/startup.json with the load
average.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

from bench.output import write_json
from mover6_control.nodes.runtime import local_dds
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GOAL_MS = 3000.0           # the goal: ready within 3 s of the command
PLAN_MS = 50.0             # and the first goal planned within 50 ms
TIMEOUT = 60.0
CLK_TCK = os.sysconf('SC_CLK_TCK')


def stat_fields(pid):
    """Return the fields of /proc/<pid>/stat after the command name (field 3 on)."""
    with open(f'/proc/{pid}/stat') as f:
        return f.read().rsplit(')', 1)[1].split()


def cpu_by_process(launch_pid):
    """
    Return {name: CPU seconds so far} of launch.sh's children, and of launch.sh itself.

    A child's name is its executable's (the node); ``launch.sh`` counts its own CPU and that of
    the children it has waited for (the short commands before the nodes start).
    """
    cpu = {}
    fields = stat_fields(launch_pid)
    cpu['launch.sh'] = sum(int(x) for x in fields[11:15]) / CLK_TCK   # utime stime cutime cstime
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            fields = stat_fields(entry)
            if int(fields[1]) != launch_pid:
                continue
            with open(f'/proc/{entry}/cmdline', 'rb') as f:
                argv = f.read().split(b'\0')
        except (OSError, IndexError, ValueError):
            continue
        name = next((os.path.basename(a.decode()) for a in argv[:3]
                     if b'/lib/mover6_control/' in a), os.path.basename(argv[0].decode()))
        cpu[name] = cpu.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / CLK_TCK
    return cpu


class Probe:
    """The goal client, running before the launch, with the timestamps of what it hears."""

    def __init__(self, namespace):
        """Create the client in ``namespace`` (rclpy initialised here)."""
        from diagnostic_msgs.msg import DiagnosticStatus
        from mover6_control.nodes.messages import conversions
        from mover6_control.nodes.messages.demand_messages import demand_id_from_msg
        from mover6_control.tools.goal_cli import GoalClient
        import rclpy
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float32MultiArray

        self.rclpy, self.conversions, self.demand_id = rclpy, conversions, demand_id_from_msg
        rclpy.init(args=['--ros-args', '-r', f'__ns:=/{namespace}'])
        self.client = GoalClient(name='bench_startup')
        self.first = {}
        self.demands, self.executing = [], []
        qos = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.client.create_subscription(JointState, 'joint_states', self.on_state, 10)
        self.client.create_subscription(DiagnosticStatus, 'controller/status',
                                        self.on_controller, qos)
        self.client.create_subscription(DiagnosticStatus, 'planner/status', self.on_planner,
                                        qos)
        self.client.create_subscription(Float32MultiArray, 'joint_demands', self.on_demand, 10)

    def note(self, what):
        """Keep the first time ``what`` happened."""
        self.first.setdefault(what, time.perf_counter())

    def on_state(self, msg):
        """Note the first /joint_states."""
        self.note('joint_states')

    def on_controller(self, msg):
        """Note the controller past waiting for states; keep the time of each 'executing'."""
        values = self.conversions.status_values(msg)
        if values.get('state') not in (None, 'waiting_for_states'):
            self.note('controller')
        if values.get('state') == 'executing':
            self.executing.append(time.perf_counter())

    def on_planner(self, msg):
        """Note the planner ready."""
        if self.conversions.status_values(msg).get('state') == 'ready':
            self.note('planner')

    def on_demand(self, msg):
        """Keep the time of each demand heard."""
        self.demands.append(time.perf_counter())

    def ready(self):
        """Return True when every check of the client's readiness holds now."""
        c = self.client
        return ('joint_states' in self.first and 'controller' in self.first
                and 'planner' in self.first and c.q is not None
                and c.pose_pub.get_subscription_count() > 0
                and c.on_topic('joint_demands', 'planner', 'controller'))

    def spin_until(self, predicate, timeout):
        """Spin until ``predicate()`` or ``timeout`` [s]; return the time it held or None."""
        return self.client.spin_until(predicate, timeout) and time.perf_counter()

    def close(self):
        """Destroy the client and shut rclpy down."""
        self.client.destroy_node()
        self.rclpy.try_shutdown()


def goal_msg():
    """Return the planner bench's first pose goal as a PoseStamped."""
    from geometry_msgs.msg import PoseStamped
    from mover6_control.kinematics.rotations import pose_from_xyzabc
    from mover6_control.nodes.messages import conversions
    msg = PoseStamped()
    msg.header.frame_id = 'base_link'
    msg.pose = conversions.matrix_to_pose(pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0))
    return msg


def stop(proc):
    """Stop launch.sh (SIGINT: it stops its nodes), by pid; wait for it."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def run_once(root, log_dir, index):
    """Launch once with the client already running; return the times [s] and the goal [ms]."""
    namespace = f'bench_startup_{os.getpid()}_{index}'
    probe = Probe(namespace)
    msg = goal_msg()
    probe.client.spin_until(lambda: False, 0.3)       # the client's own discovery settles
    out = open(os.path.join(log_dir, f'launch{index}.log'), 'w')
    t0 = time.perf_counter()
    proc = subprocess.Popen(['bash', os.path.join(root, 'scripts', 'launch.sh'),
                             '--namespace', f'/{namespace}'],
                            stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        t_ready = probe.spin_until(lambda: probe.ready() or proc.poll() is not None, TIMEOUT)
        if not t_ready or proc.poll() is not None:
            raise RuntimeError(f'not ready within {TIMEOUT} s (seen: {sorted(probe.first)}); '
                               f'log {out.name}')
        cpu = cpu_by_process(proc.pid)
        probe.demands.clear()
        probe.executing.clear()
        t_goal = time.perf_counter()
        probe.client.pose_pub.publish(msg)
        probe.spin_until(lambda: probe.demands and probe.executing, 20.0)
        row = {what: t - t0 for what, t in probe.first.items()}
        row['ready'] = t_ready - t0
        row['first_goal_planned_ms'] = ((probe.demands[0] - t_goal) * 1e3 if probe.demands
                                        else float('nan'))
        row['first_goal_exec_ms'] = ((probe.executing[0] - t_goal) * 1e3 if probe.executing
                                     else float('nan'))
        row['cpu_s_at_ready'] = cpu
        row['load_average'] = list(os.getloadavg())
        return row
    finally:
        stop(proc)
        out.close()
        probe.close()


def main(argv=None):
    """Run the launch ``--repeat`` times; print the table and write bench/results/startup.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='two runs instead of five')
    parser.add_argument('--repeat', type=int, default=5, help='launches, one after another')
    parser.add_argument('--root', default=ROOT, help='the checkout whose scripts/launch.sh runs')
    args = parser.parse_args(argv)
    local_dds.apply_default(os.environ)    # the client's DDS as the launchers'
    repeat = 2 if args.quick else args.repeat
    log_dir = tempfile.mkdtemp(prefix='bench_startup_')
    load = os.getloadavg()
    print(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs; '
          f'{os.path.join(args.root, "scripts", "launch.sh")}; logs in {log_dir}', flush=True)
    runs = []
    for i in range(repeat):
        runs.append(run_once(args.root, log_dir, i + 1))
        time.sleep(1.0)       # the last stack's processes gone from the graph
    cols = ('joint_states', 'controller', 'planner', 'ready')
    print(f'\nseconds from the launch command; goal: ready <= {GOAL_MS / 1e3:g} s, the first goal '
          f'planned <= {PLAN_MS:g} ms')
    print(f'{"run":>3} ' + ' '.join(f'{c:>12}' for c in cols)
          + f' {"planned [ms]":>12} {"exec [ms]":>10} {"load 1 min":>10}')
    for i, r in enumerate(runs):
        print(f'{i + 1:>3} ' + ' '.join(f'{r.get(c, float("nan")):12.2f}' for c in cols)
              + f' {r["first_goal_planned_ms"]:12.1f} {r["first_goal_exec_ms"]:10.1f}'
              f' {r["load_average"][0]:10.2f}')
    for i, r in enumerate(runs):
        print(f'CPU seconds at ready, run {i + 1}: '
              + ', '.join(f'{k} {v:.2f}' for k, v in sorted(r['cpu_s_at_ready'].items())))
    ready = [r['ready'] for r in runs]
    planned = [r['first_goal_planned_ms'] for r in runs]
    summary = {'ready_median_s': float(np.median(ready)), 'ready_max_s': float(np.max(ready)),
               'first_goal_planned_median_ms': float(np.median(planned)),
               'first_goal_planned_max_ms': float(np.max(planned))}
    print(f'median ready {summary["ready_median_s"]:.2f} s (max {summary["ready_max_s"]:.2f}); '
          f'first goal planned median {summary["first_goal_planned_median_ms"]:.1f} ms')
    write_json('startup', {'root': args.root, 'cpus': os.cpu_count(),
                           'load_average_at_start': list(load), 'runs': runs, **summary})
    return 0


if __name__ == '__main__':
    sys.exit(main())
