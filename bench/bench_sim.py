"""
Benchmark of the MuJoCo bridge: physics speed, real-time pacing, CPU and JointJog latency.

Run inside the ROS environment: ``./run.sh exec python -m bench.bench_sim [--quick]``. Prints a
table and writes ``bench/results/sim.json``. ROS traffic stays on localhost, domain 31.

1. Physics steps per second, as fast as possible: the bare ``Simulator`` (no ROS); the node at
   real_time_factor 0 publishing /joint_states at 100 Hz of sim time; the same plus /clock on
   every step.
2. Real-time pacing at factor 1.0 with /joint_states at 100 and 500 Hz: the node runs in its own
   process; the achieved factor is sim time ((messages - 1) / rate) over the wall time between
   the first and the last message's arrival, and CPU
   is the process's user + system time over wall time (from /proc), in % of one core.
   Goals: factor within 1 %, CPU under 30 % of one core at 100 Hz.
3. Latency from a /JointJog's arrival in the node's callback to the end of the first physics
   step that applies it (node in this process, paced at 1.0, commands at 100 Hz).
"""

import argparse
import os
import subprocess
import sys
import threading
import time

from bench.output import write_json
from mover6_control.nodes.runtime import local_dds

local_dds.apply_default(os.environ)   # the launchers' DDS (loopback only), before rclpy
os.environ.setdefault('ROS_DOMAIN_ID', os.environ.get('BENCH_SIM_DOMAIN_ID', '31'))

from control_msgs.msg import JointJog  # noqa: E402, I100
from mover6_control.kinematics.arm import mover6  # noqa: E402
import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from sim_bridge.bridge_node import SimBridgeNode  # noqa: E402
from sim_bridge.simulator import Simulator  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLK_TCK = os.sysconf('SC_CLK_TCK')


def bare_steps_per_second(duration):
    """Return physics steps per second of the bare Simulator under a renewed command."""
    arm = mover6()
    sim = Simulator(arm)
    v = 0.3 * arm.velocity_limits
    steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < duration:
        sim.set_command(arm.joint_names, v, sim.time)
        sim.step(50)
        steps += 50
        if steps % 5000 == 0:
            sim.reset()
    return steps / (time.perf_counter() - t0)


def _spin_in_thread(executor, stop):
    """Spin ``executor`` until ``stop`` is set."""
    while not stop.is_set():
        executor.spin_once(timeout_sec=0.01)


def node_steps_per_second(duration, publish_clock):
    """Return physics steps per second of the node at real_time_factor 0 (in this process)."""
    params = [Parameter('real_time_factor', value=0.0), Parameter('publish_rate', value=100.0),
              Parameter('publish_clock', value=publish_clock)]
    node = SimBridgeNode(parameter_overrides=params)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()
    spinner = threading.Thread(target=_spin_in_thread, args=(executor, stop))
    spinner.start()
    try:
        time.sleep(0.2)
        s0, t0 = node.sim.step_count, time.perf_counter()
        time.sleep(duration)
        rate = (node.sim.step_count - s0) / (time.perf_counter() - t0)
    finally:
        stop.set()
        spinner.join()
        executor.shutdown()
        node.destroy_node()
    return rate


def _cpu_seconds(pid):
    """Return user + system CPU time [s] of process ``pid`` (Linux /proc)."""
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def paced_run(rate, duration):
    """
    Run the node as a process at real_time_factor 1.0 and /joint_states at ``rate`` [Hz].

    Return (achieved real-time factor, CPU % of one core, messages counted).
    """
    cmd = [sys.executable, '-m', 'sim_bridge.bridge_node', '--ros-args', '-p',
           'real_time_factor:=1.0', '-p', f'publish_rate:={rate}']
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    node = rclpy.create_node('bench_sim_listener')
    arrivals = []
    node.create_subscription(JointState, 'joint_states',
                             lambda msg: arrivals.append(time.monotonic()), 1000)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while len(arrivals) < 50 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if len(arrivals) < 50:
            raise RuntimeError('the sim_bridge process published no /joint_states')
        n0, w0, c0 = len(arrivals), time.monotonic(), _cpu_seconds(proc.pid)
        while time.monotonic() < w0 + duration:
            executor.spin_once(timeout_sec=0.01)
        n1, w1, c1 = len(arrivals), time.monotonic(), _cpu_seconds(proc.pid)
    finally:
        proc.send_signal(2)
        try:
            proc.wait(10.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5.0)
        executor.shutdown()
        node.destroy_node()
    window = arrivals[n0:n1]          # sim time between first and last = (count - 1) / rate
    factor = (len(window) - 1) / rate / (window[-1] - window[0])
    return factor, 100.0 * (c1 - c0) / (w1 - w0), len(window)


def jog_latency(duration):
    """Return JointJog arrival-to-applied latencies [s] of the node paced at 1.0."""
    # physics_priority 0: at real-time priority here it would raise this process's threads too.
    node = SimBridgeNode(parameter_overrides=[Parameter('real_time_factor', value=1.0),
                                              Parameter('physics_priority', value=0)])
    talker = rclpy.create_node('bench_sim_talker')
    pub = talker.create_publisher(JointJog, 'JointJog', 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    executor.add_node(talker)
    names = list(node.arm.joint_names)
    try:
        t_end = time.monotonic() + duration
        next_send = time.monotonic()
        k = 0
        while time.monotonic() < t_end:
            if time.monotonic() >= next_send:
                sign = 1.0 if (k // 50) % 2 == 0 else -1.0      # swing back and forth
                msg = JointJog(joint_names=names, velocities=[0.1 * sign] * 6)
                pub.publish(msg)
                k += 1
                next_send += 0.01
            executor.spin_once(timeout_sec=0.002)
        return np.array(node.physics.latencies)
    finally:
        executor.shutdown()
        node.destroy_node()
        talker.destroy_node()


def main(argv=None):
    """Run the benchmark, print the table, write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--quick', action='store_true', help='short runs (under 20 s)')
    args = parser.parse_args(argv)
    quick = args.quick
    rclpy.init()
    try:
        results = {'quick': quick}
        bare = bare_steps_per_second(0.3 if quick else 3.0)
        node_js = node_steps_per_second(0.5 if quick else 3.0, publish_clock=False)
        node_clock = node_steps_per_second(0.5 if quick else 3.0, publish_clock=True)
        results['steps_per_second'] = {'simulator_no_ros': bare,
                                       'node_joint_states_100hz': node_js,
                                       'node_joint_states_and_clock': node_clock}
        paced = {}
        for rate in (100.0, 500.0):
            factor, cpu, count = paced_run(rate, 2.0 if quick else 10.0)
            paced[f'{int(rate)}hz'] = {'real_time_factor': factor, 'cpu_percent': cpu,
                                       'messages': count}
        results['paced_rtf_1'] = paced
        lat = jog_latency(1.0 if quick else 5.0)
        results['jog_latency_ms'] = {
            'count': int(lat.size), 'median': float(np.median(lat) * 1e3),
            'p95': float(np.percentile(lat, 95) * 1e3), 'max': float(np.max(lat) * 1e3)}
    finally:
        rclpy.try_shutdown()

    print('\nMuJoCo bridge benchmark' + (' (quick)' if quick else ''))
    print(f'{"measure":<52}{"value":>14}')
    sps = results['steps_per_second']
    print(f'{"physics steps/s, Simulator alone (no ROS)":<52}{sps["simulator_no_ros"]:>14.0f}')
    print(f'{"physics steps/s, node rtf 0, /joint_states 100 Hz":<52}'
          f'{sps["node_joint_states_100hz"]:>14.0f}')
    print(f'{"physics steps/s, node rtf 0, + /clock every step":<52}'
          f'{sps["node_joint_states_and_clock"]:>14.0f}')
    for key, row in results['paced_rtf_1'].items():
        print(f'{"real-time factor at 1.0, /joint_states " + key:<52}'
              f'{row["real_time_factor"]:>14.4f}')
        print(f'{"CPU [% of one core], /joint_states " + key:<52}{row["cpu_percent"]:>14.1f}')
    lat = results['jog_latency_ms']
    print(f'{"JointJog arrival -> applied step, median [ms]":<52}{lat["median"]:>14.3f}')
    print(f'{"JointJog arrival -> applied step, p95 / max [ms]":<52}'
          f'{lat["p95"]:>7.3f} / {lat["max"]:.3f}')
    write_json('sim', results)
    return 0


if __name__ == '__main__':
    sys.exit(main())
