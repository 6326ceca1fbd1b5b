"""
Speed of jogging: per-tick compute of the servo, and twist-to-JointJog latency.

Part 1, in this process without ROS: ``ControllerCore.on_named_joint_states`` + ``on_twist``
+ ``tick`` while jogging a simulated arm along a line (twist mode, base frame), back and forth, and
again near the wrist singularity (where the slow-down looks ahead: more kinematics per tick), and
in joint mode: median and p99 of one tick [us]. Goal: p99 < 1 ms.

Part 2, over DDS: the controller node in its own process at 100 Hz; this process plays the arm
(integrates /JointJog, publishes /joint_states at 100 Hz) and, from rest, sends one TwistStamped
to /controller/delta_twist_cmds, then waits for the first non-zero /JointJog (the first that
reflects it), and again after the arm is back at rest. Latency [ticks of 10 ms]: from the
twist's stamp to the stamp of that JointJog (inside the controller: waiting for the next tick),
and to its arrival here (DDS both ways too). Goal: p95 under 2 ticks.

Run: ``python -m bench.bench_servo [--quick]``; writes bench/results/servo.json.
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
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import jacobian
from mover6_control.nodes.runtime import local_dds
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DT = 0.01
RATE = 100.0
Q_AWAY = np.array([0.0, 0.3, 0.6, 0.0, 0.8, 0.0])
Q_NEAR_WRIST = np.array([0.0, 0.3, 0.6, 0.0, 0.25, 0.0])   # condition ~18: slowing down


def bench_compute(case, n_ticks):
    """Return the tick times [s] of ``n_ticks`` jogging ticks of ``case``."""
    arm = mover6()
    core = ControllerCore(arm, ControllerConfig())
    q0 = Q_NEAR_WRIST if case == 'near singularity' else Q_AWAY
    q, t = q0.copy(), 0.0
    names = core.robot.joint_names
    core.on_named_joint_states(t, names, q)
    core.tick(t)
    column = jacobian(arm, q0)[:, 4] * 0.05
    clock = time.perf_counter
    times = []
    for k in range(n_ticks):
        sign = 1.0 if (k // 100) % 2 == 0 else -1.0           # back and forth, 1 s each way
        t0 = clock()
        core.on_named_joint_states(t, names, q)
        if case == 'line':
            core.on_twist(t, t, [0.02 * sign, 0.0, 0.0], [0.0, 0.0, 0.0])
        elif case == 'near singularity':
            core.on_twist(t, t, -sign * column[:3], -sign * column[3:])
        else:
            core.on_joint_jog(t, t, ['joint2', 'joint3'], [0.1 * sign, -0.1 * sign])
        out = core.tick(t)
        times.append(clock() - t0)
        q = q + out.qd * DT
        t += DT
    return np.array(times)


class ControllerProcess(NodeProcess):
    """The controller node from this source tree in its own process, stopped by its pid."""

    def __init__(self, log_dir, namespace):
        cmd = [sys.executable, '-m', 'mover6_control.nodes.controller.node', '--ros-args',
               '--params-file', os.path.join(ROOT, 'config', 'controller.yaml'),
               '-p', f'rate:={RATE}', '-r', f'__ns:=/{namespace}']
        super().__init__(cmd, os.path.join(log_dir, 'controller.log'), ROOT)


def bench_latency(samples, log_dir):
    """Return the twist-to-JointJog latencies [s] (to the tick, to arrival here) of samples."""
    from control_msgs.msg import JointJog
    from geometry_msgs.msg import TwistStamped
    from mover6_control.nodes.messages import conversions
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    namespace = f'bench_servo_{os.getpid()}'      # no cross-talk with tests on the domain
    proc = ControllerProcess(log_dir, namespace)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node('bench_servo_arm', context=context, namespace=namespace)
    names = list(mover6().joint_names)
    sim = {'q': Q_AWAY.copy(), 'qd': np.zeros(6), 'last': time.monotonic()}
    jogs = []        # (arrival monotonic, stamp [s], velocities)

    def on_jog(msg):
        jogs.append((time.monotonic(), conversions.stamp_to_seconds(msg.header.stamp),
                     np.array(msg.velocities)))
        sim['qd'] = np.array(msg.velocities)

    def on_timer():
        now = time.monotonic()
        sim['q'] = sim['q'] + sim['qd'] * min(now - sim['last'], 0.05)
        sim['last'] = now
        state_pub.publish(conversions.make_joint_state(names, sim['q'], sim['qd']))

    state_pub = node.create_publisher(JointState, 'joint_states', 10)
    twist_pub = node.create_publisher(TwistStamped, 'controller/delta_twist_cmds', 10)
    node.create_subscription(JointJog, 'JointJog', on_jog, 50)
    node.create_timer(1.0 / RATE, on_timer)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def spin_until(predicate, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.002)
            if predicate():
                return True
        return False

    to_tick, to_here = [], []
    try:
        if not spin_until(lambda: len(jogs) > 20, 30.0):
            raise RuntimeError('controller node did not come up:\n' + proc.tail())
        spin_until(lambda: False, 0.5)
        for k in range(samples):
            spin_until(lambda: len(jogs) > 5 and not any(np.any(v) for _, _, v in jogs[-5:]),
                       5.0)
            msg = TwistStamped()
            msg.header.frame_id = 'base_link'
            msg.twist.linear.x = 0.02 if k % 2 == 0 else -0.02
            n_before = len(jogs)
            sent = time.monotonic()
            stamp = node.get_clock().now().nanoseconds * 1e-9
            msg.header.stamp = conversions.seconds_to_stamp(stamp)
            twist_pub.publish(msg)
            if not spin_until(lambda: any(np.any(v) for _, _, v in jogs[n_before:]), 1.0):
                raise RuntimeError('no JointJog reflected the twist:\n' + proc.tail())
            arrival, jog_stamp, _ = next(j for j in jogs[n_before:] if np.any(j[2]))
            to_tick.append(jog_stamp - stamp)
            to_here.append(arrival - sent)
            spin_until(lambda: False, 0.3)         # stale, then at rest: idle again
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        proc.stop()
    return np.array(to_tick), np.array(to_here)


def main(argv=None):
    """Run the benchmark; print the tables and write bench/results/servo.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer ticks and samples')
    parser.add_argument('--no-node', action='store_true', help='only the compute part')
    args = parser.parse_args(argv)
    n_ticks, samples = (2000, 30) if args.quick else (20000, 100)
    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    os.environ.setdefault('ROS_DOMAIN_ID', '33')
    results = {'quick': args.quick, 'compute': [], 'latency': None,
               'load_average_1min_at_start': os.getloadavg()[0], 'cpus': os.cpu_count()}
    print(f'load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs '
          '(other processes on the machine disturb every figure below)\n')
    print(f'Jogging compute per tick ({n_ticks} ticks per case, goal p99 < 1 ms)')
    print(f'{"case":>17} {"median [us]":>12} {"p99 [us]":>10} {"max [us]":>10}')
    for case in ('line', 'near singularity', 'joint jog'):
        times = bench_compute(case, n_ticks)
        row = {'case': case, 'tick_median_us': float(np.median(times) * 1e6),
               'tick_p99_us': float(np.percentile(times, 99) * 1e6),
               'tick_max_us': float(np.max(times) * 1e6), 'ticks': n_ticks}
        results['compute'].append(row)
        print(f'{case:>17} {row["tick_median_us"]:12.1f} {row["tick_p99_us"]:10.1f} '
              f'{row["tick_max_us"]:10.1f}')

    if not args.no_node:
        print(f'\nTwist to the first JointJog reflecting it, controller node at {RATE:g} Hz, '
              f'{samples} samples from rest (goal p95 < 2 ticks)')
        to_tick, to_here = bench_latency(samples, tempfile.mkdtemp(prefix='bench_servo_'))
        tick = 1.0 / RATE
        row = {'rate_hz': RATE, 'samples': int(len(to_tick))}
        print(f'{"":>26} {"median":>8} {"p95":>8} {"max":>8}   [ticks]')
        for name, values in (('stamp to JointJog stamp', to_tick),
                             ('send to JointJog arrival', to_here)):
            key = 'to_tick' if values is to_tick else 'to_arrival'
            figures = [np.median(values) / tick, np.percentile(values, 95) / tick,
                       np.max(values) / tick]
            row.update({f'{key}_median_ticks': float(figures[0]),
                        f'{key}_p95_ticks': float(figures[1]),
                        f'{key}_max_ticks': float(figures[2])})
            print(f'{name:>26} {figures[0]:8.2f} {figures[1]:8.2f} {figures[2]:8.2f}')
        results['latency'] = row

    write_json('servo', results)


if __name__ == '__main__':
    main()
