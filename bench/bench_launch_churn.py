"""
The real-arm launch while processes join the graph: the controller's tick, the driver's states.

Set-up: ``scripts/launch.sh --hardware can-sim`` exactly as a user starts it (the CAN-level
Mover6 on a pty, the driver on it, the controller, the planner and the helpers), with the
launchers' default DDS configuration (the package's local one: UDP on 127.0.0.1, no shared
memory) or, with ``--dds localhost``, ROS's LOCALHOST. This process sends motions back
and forth (``/joint_demands``) while ``CHURN`` short-lived processes join the graph, a few at a
time, each echoing ``/controller/status`` once (as ``ros2 topic echo`` does; ``bench_churn``'s).

Figures: the controller's ``max_tick_gap`` (its status; the longest gap since it started, read
before and after the churn), the ticks the controller logged as stalled during the churn, the
largest gap between two ``/JointJog`` (one per tick) and between two ``/joint_states`` (the
driver's, one per 50 ms cycle) as this process received them, and the motions that arrived.

Run: ``python -m bench.bench_launch_churn [--quick] [--dds local|localhost] [--repeat N]``
(``./run.sh bench launch_churn``; ``MOVER6_NETNS=0`` for the host network); writes
bench/results/launch_churn.json.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

from bench.bench_churn import Churn
from bench.output import write_json
from mover6_control.nodes.runtime import local_dds
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHURN, CHURN_QUICK = 40, 12
MOTIONS = np.array([[0.4, -0.3, 0.3, 0.4, -0.3, 0.5], [-0.3, 0.2, -0.3, -0.4, 0.3, -0.4]])
STALL_LINE = 'the tick thread stalled'


def dds_environment(dds):
    """Return this environment with DDS configuration ``dds`` (``local`` or ``localhost``)."""
    env = {k: v for k, v in os.environ.items() if k not in local_dds.USER_DDS_ENV}
    env['MOVER6_DDS'] = dds
    local_dds.apply_default(env)
    return env


def run_once(dds, total, log_dir):
    """Launch the can-sim stack, churn during motions; return the figures."""
    from control_msgs.msg import JointJog
    from diagnostic_msgs.msg import DiagnosticStatus
    from mover6_control.nodes.messages import conversions, demand_messages
    from mover6_control.nodes.runtime.qos import STATUS_QOS
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float32MultiArray

    namespace = f'launch_churn_{os.getpid()}_{int(time.monotonic() * 1e3) % 100000}'
    env = dds_environment(dds)
    for key in local_dds.USER_DDS_ENV:        # this process and the joining ones: the same DDS
        os.environ.pop(key, None)
    os.environ.update({k: v for k, v in env.items() if k in local_dds.USER_DDS_ENV})
    launch = subprocess.Popen(
        ['bash', os.path.join(ROOT, 'scripts', 'launch.sh'), '--hardware', 'can-sim',
         '--limit-set', 'hardware', '--namespace', f'/{namespace}', '--log-dir', log_dir],
        env=env, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('bench_launch_churn', namespace=f'/{namespace}', context=context)
    jogs, states, statuses = [], [], []
    node.create_subscription(JointJog, 'JointJog', lambda m: jogs.append(time.monotonic()), 100)
    node.create_subscription(JointState, 'joint_states',
                             lambda m: states.append(time.monotonic()), 100)
    node.create_subscription(DiagnosticStatus, 'controller/status',
                             lambda m: statuses.append(conversions.status_values(m)), STATUS_QOS)
    demand_pub = node.create_publisher(Float32MultiArray, 'joint_demands', 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    churn = Churn(f'/{namespace}/controller/status', total, log_dir)
    results = []
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and not (
                statuses and statuses[-1].get('state') == 'idle' and len(states) > 40):
            executor.spin_once(timeout_sec=0.05)
        if not statuses or statuses[-1].get('state') != 'idle':
            raise RuntimeError(f'the launched stack did not become idle within 120 s '
                               f'(last status {statuses[-1:]}); logs in {log_dir}')
        gap_before = float(statuses[-1].get('max_tick_gap', 'nan'))
        t0, wall_t0 = time.monotonic(), time.time()
        waiting, sent, sent_at = None, 0, t0
        while True:
            churning = churn.step()
            executor.spin_once(timeout_sec=0.02)
            status = statuses[-1]
            if waiting is not None:
                if int(status.get('motion_id', 0)) == waiting and \
                        status.get('state') in ('idle', 'fault'):
                    results.append(status.get('result', '?'))
                    waiting = None
                elif time.monotonic() - sent_at > 60.0:
                    results.append('no end seen')
                    waiting = None
            if waiting is None:
                if not churning or time.monotonic() - t0 > 600.0:
                    break
                if status.get('state') != 'idle':
                    continue
                demand_pub.publish(demand_messages.make_demands(MOTIONS[sent % 2][None, :]))
                sent += 1
                waiting = int(status.get('motion_id', 0)) + 1
                sent_at = time.monotonic()
        t1, wall_t1 = time.monotonic(), time.time()
        gap_after = float(statuses[-1].get('max_tick_gap', 'nan'))
    finally:
        churn.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        os.killpg(launch.pid, signal.SIGINT)
        try:
            launch.wait(30.0)
        except subprocess.TimeoutExpired:
            os.killpg(launch.pid, signal.SIGKILL)
            launch.wait(5.0)
    stalls = 0
    with open(os.path.join(log_dir, 'controller.log')) as log:
        for line in log:
            if STALL_LINE in line:
                stamp = line.split('[')[2].split(']')[0] if line.count('[') >= 2 else ''
                try:
                    stalls += wall_t0 <= float(stamp) <= wall_t1
                except ValueError:
                    pass

    def largest_gap(times):
        inside = np.array([t for t in times if t0 <= t <= t1])
        return float(np.max(np.diff(inside)) * 1e3) if len(inside) > 1 else float('nan')
    return {'dds': dds, 'churn_processes': total, 'seconds': t1 - t0,
            'churn_saw_status': sum(1 for c in churn.exit_codes if c == 0),
            'controller_max_tick_gap_ms_before': gap_before * 1e3,
            'controller_max_tick_gap_ms_after': gap_after * 1e3,
            'controller_stall_warnings': stalls,
            'jointjog_max_gap_ms': largest_gap(jogs),
            'joint_states_max_gap_ms': largest_gap(states),
            'motions_sent': sent, 'motions_arrived': results.count('arrived'),
            'motion_results': results, 'log_dir': log_dir}


def main(argv=None):
    """Run the benchmark; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help=f'{CHURN_QUICK} joining processes')
    parser.add_argument('--dds', choices=('local', 'localhost'), default='local',
                        help='the DDS configuration of every process (default: local, the '
                        'default of the launchers; one per run: Fast DDS reads its profile once)')
    parser.add_argument('--repeat', type=int, default=1, help='runs of each configuration')
    args = parser.parse_args(argv)
    total = CHURN_QUICK if args.quick else CHURN
    tmp = tempfile.mkdtemp(prefix='bench_launch_churn_')
    load = os.getloadavg()[0]
    print(f'load average {load:.2f} on {os.cpu_count()} CPUs; {total} joining processes; '
          f'logs in {tmp}', flush=True)
    rows = []
    for k in range(args.repeat):
        for dds in [args.dds]:
            log_dir = os.path.join(tmp, f'{dds}_{k}')
            os.makedirs(log_dir)
            row = run_once(dds, total, log_dir)
            rows.append(row)
            print(f'{dds:9s} run {k + 1}: controller max tick gap '
                  f'{row["controller_max_tick_gap_ms_after"]:.1f} ms (before the churn '
                  f'{row["controller_max_tick_gap_ms_before"]:.1f}), '
                  f'stalls logged {row["controller_stall_warnings"]}, largest /JointJog gap '
                  f'{row["jointjog_max_gap_ms"]:.1f} ms, /joint_states gap '
                  f'{row["joint_states_max_gap_ms"]:.1f} ms, {row["churn_saw_status"]}/{total} '
                  f'joined, motions {row["motions_arrived"]}/{row["motions_sent"]} arrived',
                  flush=True)
    write_json('launch_churn', {'load_average_1min_at_start': load, 'cpus': os.cpu_count(),
                                'rows': rows})
    return 0 if all(r['motions_arrived'] == r['motions_sent'] for r in rows) else 1


if __name__ == '__main__':
    sys.exit(main())
