"""
Speed of the controller: per-tick compute time of the control law, and node jitter.

Part 1, in this process without ROS: ``ControllerCore.on_named_joint_states`` + ``tick`` per
profile against a simulated arm, many motions in a row: median and p99 of one tick [us], and the
time to check, plan and start a demand [ms] (the calls of the node's demand thread, not in the
tick). Goal: tick p99 < 1 ms.

Part 2, over DDS: the controller node in its own process at 100 Hz and 500 Hz while it executes
a motion (this process plays the arm: integrates /JointJog, publishes /joint_states at 50 Hz).
Tick jitter = |period - 1/rate| between the starts of consecutive ticks, recorded inside the
node process (a receiver over DDS cannot keep up at 500 Hz and would measure itself), p99 [ms];
the /JointJog messages this process received are counted too. CPU = the node process's user +
system time over wall time [% of one core]. Goals at 100 Hz: p99 < 2 ms, CPU < 15 %.

Run: ``python -m bench.bench_controller [--quick]``; writes bench/results/controller.json.
"""

import argparse
import os
import sys
import tempfile
import time

from bench.output import write_json
from bench.processes import NodeProcess
from mover6_control.control.controller_config import ControllerConfig
from mover6_control.control.controller_core import ControllerCore
from mover6_control.control.profiles import LawConfig, PROFILES
from mover6_control.kinematics.arm import mover6
from mover6_control.nodes.runtime import local_dds
import numpy as np

DT = 0.01
MOTION = np.array([[0.4, -0.3, 0.2, 0.3, -0.2, 0.5], [0.1, 0.2, -0.2, 0.0, 0.3, -0.4],
                   [-0.3, 0.1, 0.3, -0.2, 0.1, 0.2]])


def bench_compute(profile, n_ticks):
    """Return tick times [s] and plan times [s] for ``profile`` over ``n_ticks`` ticks."""
    core = ControllerCore(mover6('hardware'),
                          ControllerConfig(law=LawConfig(profile=profile)))
    q, t, k = np.zeros(6), 0.0, 0
    tick_times, plan_times = [], []
    clock = time.perf_counter
    names = core.robot.joint_names
    core.on_named_joint_states(t, names, q)
    core.tick(t)
    for _ in range(n_ticks):
        if core.state == 'idle':
            goal = MOTION[k % len(MOTION)] if k % 2 == 0 else MOTION[::-1]
            k += 1
            t0 = clock()
            Q = core.check_demand(np.atleast_2d(goal))    # as the node's demand thread
            core.commit_demand(core.prepare_demand(t, Q, core.snapshot()))
            plan_times.append(clock() - t0)
        t0 = clock()
        core.on_named_joint_states(t, names, q)
        out = core.tick(t)
        tick_times.append(clock() - t0)
        q = q + out.qd * DT
        t += DT
    return np.array(tick_times), np.array(plan_times)


def proc_cpu_seconds(pid):
    """Return the user + system CPU time [s] of process ``pid`` (Linux /proc)."""
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class SourceNode(NodeProcess):
    """
    The controller node from this source tree in its own process, stopped by its pid.

    It runs through ``probe_main``, which records the monotonic time at the start of every tick.
    """

    def __init__(self, log_dir, params, probe_path, namespace):
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        cmd = [sys.executable, '-m', 'bench.bench_controller', '--probe', probe_path,
               '--ros-args', '--params-file', os.path.join(root, 'config', 'controller.yaml')]
        for key, value in params.items():
            cmd += ['-p', f'{key}:={value}']
        cmd += ['-r', f'__ns:=/{namespace}']
        super().__init__(cmd, os.path.join(log_dir, f'controller_{params["rate"]:g}.log'), root)


def bench_node(rate, seconds, log_dir):
    """Start the controller node at ``rate`` [Hz]; return jitter and CPU figures."""
    from control_msgs.msg import JointJog
    from mover6_control.nodes.messages import conversions, demand_messages
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float32MultiArray

    probe_path = os.path.join(log_dir, f'ticks_{rate:g}.npy')
    namespace = f'bench_controller_{os.getpid()}'     # no cross-talk with tests on the domain
    node_proc = SourceNode(log_dir, {'rate': rate, 'profile': 'trapezoidal',
                                     't_max': 2.0 * seconds}, probe_path, namespace)
    context = rclpy.Context()
    rclpy.init(context=context)
    arm = Node('bench_controller_arm', context=context, namespace=namespace)
    names = list(mover6().joint_names)
    sim = {'q': np.zeros(6), 'qd': np.zeros(6), 'last': time.monotonic()}
    stamps = []

    def on_jog(msg):
        stamps.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
        sim['qd'] = np.array(msg.velocities)

    def on_timer():
        now = time.monotonic()
        sim['q'] = sim['q'] + sim['qd'] * min(now - sim['last'], 0.05)
        sim['last'] = now
        state_pub.publish(conversions.make_joint_state(names, sim['q'], sim['qd']))

    state_pub = arm.create_publisher(JointState, 'joint_states', 10)
    demand_pub = arm.create_publisher(Float32MultiArray, 'joint_demands', 10)
    arm.create_subscription(JointJog, 'JointJog', on_jog, 50)
    arm.create_timer(0.02, on_timer)

    def spin_for(duration):
        end = time.monotonic() + duration
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.005)

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(arm)
    try:
        deadline = time.monotonic() + 30.0
        while len(stamps) < 10 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
        if len(stamps) < 10:
            raise RuntimeError('controller node did not come up:\n' + node_proc.tail())
        spin_for(0.5)                                     # let it see /joint_states
        demand_pub.publish(demand_messages.make_demands(MOTION[:1] * 0.5))
        spin_for(0.3)
        stamps.clear()
        cpu0, wall0 = proc_cpu_seconds(node_proc.pid), time.monotonic()
        spin_for(seconds)
        wall1 = time.monotonic()
        cpu = (proc_cpu_seconds(node_proc.pid) - cpu0) / (wall1 - wall0)
        delivered = len(stamps)
    finally:
        executor.shutdown()
        arm.destroy_node()
        rclpy.try_shutdown(context=context)
        node_proc.stop()
    ticks = np.load(probe_path)
    ticks = ticks[(ticks >= wall0) & (ticks <= wall1)]
    periods = np.diff(ticks)
    err = np.abs(periods - 1.0 / rate)
    return {'rate_hz': rate, 'ticks': int(len(ticks)), 'expected_ticks': int(seconds * rate),
            'jointjog_received': int(delivered),
            'period_mean_ms': float(np.mean(periods) * 1e3),
            'period_error_median_ms': float(np.median(err) * 1e3),
            'period_error_p99_ms': float(np.percentile(err, 99) * 1e3),
            'period_error_max_ms': float(np.max(err) * 1e3),
            'cpu_percent_of_one_core': float(cpu * 100.0)}


def probe_main(argv):
    """Run the controller node, saving the monotonic time of every tick to ``argv[0]`` (.npy)."""
    from mover6_control.nodes.controller import node as controller_node
    from mover6_control.nodes.controller.tick_loop import TickLoop
    times = []
    on_tick = TickLoop.on_tick

    def timed_tick(loop):
        times.append(time.monotonic())
        on_tick(loop)

    TickLoop.on_tick = timed_tick
    try:
        controller_node.main(argv[1:])
    finally:
        np.save(argv[0], np.array(times))


def main(argv=None):
    """Run the benchmark; print the tables and write bench/results/controller.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer ticks, shorter node runs')
    parser.add_argument('--no-node', action='store_true', help='only the compute part')
    args = parser.parse_args(argv)
    n_ticks, seconds = (2000, 3.0) if args.quick else (20000, 10.0)
    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    os.environ.setdefault('ROS_DOMAIN_ID', '32')
    results = {'quick': args.quick, 'compute': [], 'node': [],
               'load_average_1min_at_start': os.getloadavg()[0], 'cpus': os.cpu_count()}
    print(f'load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs '
          '(other processes on the machine disturb every figure below)\n')

    print(f'Control law compute per tick ({n_ticks} ticks per profile, goal p99 < 1 ms)')
    print(f'{"profile":>14} {"median [us]":>12} {"p99 [us]":>10} {"max [us]":>10} '
          f'{"plan median [ms]":>17} {"plan max [ms]":>14}')
    for profile in PROFILES:
        ticks, plans = bench_compute(profile, n_ticks)
        row = {'profile': profile, 'tick_median_us': float(np.median(ticks) * 1e6),
               'tick_p99_us': float(np.percentile(ticks, 99) * 1e6),
               'tick_max_us': float(np.max(ticks) * 1e6),
               'plan_median_ms': float(np.median(plans) * 1e3),
               'plan_max_ms': float(np.max(plans) * 1e3), 'plans': int(len(plans))}
        results['compute'].append(row)
        print(f'{profile:>14} {row["tick_median_us"]:12.1f} {row["tick_p99_us"]:10.1f} '
              f'{row["tick_max_us"]:10.1f} {row["plan_median_ms"]:17.2f} '
              f'{row["plan_max_ms"]:14.2f}')

    if not args.no_node:
        print(f'\nController node over DDS, {seconds:g} s per rate while executing '
              '(goal at 100 Hz: period error p99 < 2 ms, CPU < 15 %)')
        print(f'{"rate [Hz]":>10} {"ticks":>7} {"received":>9} {"mean period [ms]":>17} '
              f'{"err p50 [ms]":>13} '
              f'{"err p99 [ms]":>13} {"err max [ms]":>13} {"CPU [%]":>8}')
        log_dir = tempfile.mkdtemp(prefix='bench_controller_')
        for rate in (100.0, 500.0):
            row = bench_node(rate, seconds, log_dir)
            results['node'].append(row)
            print(f'{rate:10.0f} {row["ticks"]:7d} {row["jointjog_received"]:9d} '
                  f'{row["period_mean_ms"]:17.3f} '
                  f'{row["period_error_median_ms"]:13.3f} {row["period_error_p99_ms"]:13.3f} '
                  f'{row["period_error_max_ms"]:13.3f} {row["cpu_percent_of_one_core"]:8.1f}')

    write_json('controller', results)


if __name__ == '__main__':
    if sys.argv[1:2] == ['--probe']:
        probe_main(sys.argv[2:])
    else:
        main()
