"""
Timing of the real-arm driver: its cycle on the wire, and JointJog-to-frame latency.

Set-up: the driver node in its own process, on the CPR USB2CAN framing over a pty, exactly as on
``/dev/ttyUSB0``; behind the pty, in a process of its own without ROS (``--wire``), the CAN-level
Mover6 (``sim_bridge.can_sim``: six simulated modules on the MuJoCo arm), which timestamps every
frame it decodes. This process plays the controller: it publishes /JointJog at 100 Hz, as the
controller node does (the controller and the planner themselves do not run here).

- Cycle period error [ms]: the time between two consecutive set-point frames of joint 1 as they
  arrive at the modules, minus the driver's ``cycle`` (50 ms): p50, p99, max of its magnitude,
  from the end of the start-up (reset, enable) to the end of the trials.
- JointJog-to-frame latency [ms]: from the publication of the first non-zero JointJog (the arm at
  rest before) to the arrival of the first set-point frame of joint 1 that moves: DDS, the wait
  for the driver's next cycle (0 to one cycle by design), the serial write and the pty. p50, p95,
  max over the trials.
- A cycle's six set-points [ms]: from joint 1's set-point to joint 6's on the wire, the
  ``frame_gap`` (5 ms, the vendor's) apart: whether the cycle still fits 50 ms.
- Cycle start error [ms]: the same period error from inside the driver process (the monotonic
  time at the start of every ``ArmDriver.step``, recorded by ``--probe``): the cycle itself,
  without the serial write and the pty.

The wire side (the modules on the pty, in a process of their own without ROS) runs at SCHED_FIFO
60 where allowed, above the driver's default ``cycle_priority`` 50, so that its own delays do
not count as the driver's; this process publishes the JointJog at normal priority, as a
controller does by default. The wire figures include the pty's own kernel work (a kernel
worker at normal priority moves the bytes), which no priority of ours covers.

Variants, one after the other in the same run: the driver's defaults, ``cycle_priority`` 0
(normal scheduling), and both while ``CHURN`` short-lived ROS processes join the graph, a few at
a time (the cycle must keep its period while processes join; ``bench_churn``'s
joining processes, started by a helper process). The load average is printed and stored: the
machine is shared.

Run: ``python -m bench.bench_driver [--quick] [--variant NAME]`` (``./run.sh bench driver``);
writes bench/results/driver.json.
"""

import json
import os
import subprocess
import sys
import tempfile
import threading
import time

from bench.bench_churn import Churn
from bench.output import write_json
from bench.processes import NodeProcess
from control_msgs.msg import JointJog
from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.hardware import protocol
from mover6_control.nodes.messages.conversions import make_joint_jog
from mover6_control.nodes.runtime.qos import STATUS_QOS
import numpy as np
import rclpy
from sim_bridge.can_sim import build_arm, SerialArm
from std_srvs.srv import Trigger

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NAMES = [f'joint{i}' for i in range(1, 7)]
CYCLE = 0.05
WIRE_PRIORITY = 60
CHURN = 40
# (name, driver parameters, churn processes)
VARIANTS = (('default', {}, 0), ('priority_0', {'cycle_priority': 0}, 0),
            ('frame_gap_0', {'frame_gap': 0.0}, 0),
            ('default_churn', {}, CHURN), ('priority_0_churn', {'cycle_priority': 0}, CHURN))


class Wire:
    """The CAN-level arm on a pty, recording (time, joint, position) of every set-point."""

    def __init__(self, link):
        self.server = SerialArm(build_arm(), link, link + '.control')
        self.setpoints = []
        self.lock = threading.Lock()
        receive = self.server.arm.receive

        def recorded(can_id, data, now):
            joint, _ = protocol.joint_of_id(can_id)
            command = protocol.decode_command(data) if data[:1] == b'\x14' else None
            if command is not None:
                with self.lock:
                    self.setpoints.append((now, joint, command.position))
            return receive(can_id, data, now)
        self.server.arm.receive = recorded


def wire_main(argv):
    """Serve the arm on pty link ``argv[0]`` until SIGTERM; save joint 1's set-points."""
    import signal
    try:
        from mover6_control.realtime import run_at_priority
    except ImportError:                   # a tree before the driver's cycle_priority
        scheduling = 'normal (no mover6_control.realtime)'
    else:
        scheduling = run_at_priority(WIRE_PRIORITY)[1]
    wire = Wire(argv[0])

    def stop(*_):
        wire.server.running = False
    signal.signal(signal.SIGTERM, stop)
    print('ready', flush=True)
    try:
        wire.server.run()
    finally:
        wire.server.close()
        np.save(argv[1], np.array(wire.setpoints, dtype=float).reshape(-1, 3))
        print(json.dumps({'scheduling': scheduling}), flush=True)


def wait_ready(proc, timeout=60.0):
    """Wait until ``proc`` prints its first line ('ready'); return False if it does not."""
    import select
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    return bool(ready) and proc.stdout.readline().strip() == 'ready'


def call(node, client, timeout=30.0):
    """Call a Trigger service; return (success, message)."""
    if not client.wait_for_service(timeout_sec=timeout):
        return False, 'service not available'
    future = client.call_async(Trigger.Request())
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    result = future.result()
    return (result.success, result.message) if result else (False, 'no answer')


def jog_for(node, pub, velocity, seconds):
    """Publish JointJog at 100 Hz for ``seconds``; return when the first one was published."""
    first = None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        msg = make_joint_jog(NAMES, [velocity, 0, 0, 0, 0, 0])
        if first is None:
            first = time.monotonic()
        pub.publish(msg)
        rclpy.spin_once(node, timeout_sec=0.0)
        time.sleep(0.01)
    return first


def setpoint_spans(frames, t_start, t_end):
    """
    Return, per cycle, the time from joint 1's set-point to joint 6's next one [s].

    ``frames``: (time [s], joint, position) of every set-point on the wire. With ``frame_gap``
    (5 ms) six set-points take 25 ms of the 50 ms cycle: what is left is the margin.
    """
    firsts = [t for t, j, _ in frames if j == 1 and t_start <= t <= t_end]
    lasts = np.array([t for t, j, _ in frames if j == 6])
    spans = []
    for t in firsts:
        later = lasts[lasts >= t]
        if len(later) and later[0] - t < CYCLE:
            spans.append(later[0] - t)
    return spans


def stats(values, quantiles):
    """Return the named quantiles and the max of ``values`` [ms]."""
    arr = np.asarray(values) * 1e3
    out = {f'p{q}': round(float(np.percentile(arr, q)), 2) for q in quantiles}
    out['max'] = round(float(arr.max()), 2)
    out['n'] = int(arr.size)
    return out


def run_variant(name, params, churn, trials, tmp):
    """Run one variant: a fresh wire and driver; return its figures."""
    link = os.path.join(tmp, f'{name}-can')
    wire_log = os.path.join(tmp, f'{name}_wire.npy')
    # The modules in a process of their own, without ROS: nothing of the publisher's DDS (nor
    # its interpreter lock) delays a frame's arrival time.
    wire = subprocess.Popen([sys.executable, '-m', 'bench.bench_driver', '--wire', link,
                             wire_log], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    if not wait_ready(wire):
        wire.kill()
        print(f'{name}: the wire process did not start', file=sys.stderr)
        return None
    namespace = f'bench_driver_{name}_{os.getpid()}'
    probe = os.path.join(tmp, f'{name}_cycles.npy')
    cmd = [sys.executable, '-m', 'bench.bench_driver', '--probe', probe, '--ros-args', '-r',
           f'__ns:=/{namespace}', '-p', 'can_interface:=cpr_usb2can', '-p',
           f'can_channel:={link}']
    for key, value in params.items():
        cmd += ['-p', f'{key}:={value}']
    driver = NodeProcess(cmd, os.path.join(tmp, f'{name}_driver.log'), ROOT)
    rclpy.init()
    node = rclpy.create_node('bench_driver', namespace=namespace)
    pub = node.create_publisher(JointJog, 'JointJog', 10)
    clients = {k: node.create_client(Trigger, f'driver/{k}') for k in ('reset', 'enable')}
    joining = None
    if churn:
        # Each joining process waits for this status (transient local) and leaves. They are
        # started by a process of their own: a fork of this one would hold up the wire.
        status_pub = node.create_publisher(DiagnosticStatus, 'bench_status', STATUS_QOS)
        status_pub.publish(DiagnosticStatus(name='bench_driver', message='churn'))
        joining = subprocess.Popen(
            [sys.executable, '-m', 'bench.bench_driver', '--churn', f'/{namespace}/bench_status',
             str(churn), tmp], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        for kind in ('reset', 'enable'):
            ok, message = call(node, clients[kind])
            if not ok:
                print(f'{name}: {kind} failed: {message}\n{driver.tail()}', file=sys.stderr)
                return None
        latencies, publications = [], []
        t_start = time.monotonic()                   # the driver runs: measure from here
        for _ in range(trials):
            jog_for(node, pub, 0.0, 0.4)             # at rest, set-points steady
            t_pub = jog_for(node, pub, 0.2, 0.15)
            publications.append(t_pub)
            jog_for(node, pub, 0.0, 0.1)
        t_end = time.monotonic()
    finally:
        churned = {}
        if joining is not None:
            joining.terminate()
            out, _ = joining.communicate(timeout=60)
            churned = json.loads(out.strip().splitlines()[-1]) if out.strip() else {}
        node.destroy_node()
        rclpy.try_shutdown()
        driver.stop()
        wire.terminate()
        out, _ = wire.communicate(timeout=30)
    wire_scheduling = json.loads(out.strip().splitlines()[-1])['scheduling']
    every = np.load(wire_log)
    frames = [(t, pos) for t, j, pos in every if j == 1]
    spans = setpoint_spans(every, t_start, t_end)
    for t_pub in publications:
        before = [pos for t, pos in frames if t_pub - 0.2 <= t < t_pub]
        moved = [t for t, pos in frames if t >= t_pub and before and pos != before[-1]]
        if moved:
            latencies.append(moved[0] - t_pub)
    times = [t for t, _ in frames if t_start <= t <= t_end]
    cycles = np.load(probe) if os.path.exists(probe) else np.array([])
    cycles = cycles[(cycles >= t_start) & (cycles <= t_end)]
    jogs_path = probe.replace('.npy', '_jogs.npy')
    received = np.load(jogs_path) if os.path.exists(jogs_path) else np.zeros((0, 2))
    to_node = []
    for t_pub in publications:
        later = [t for t, v in received if t >= t_pub and v != 0.0]
        if later:
            to_node.append(later[0] - t_pub)
    scheduling = [line.split('cycle thread: ', 1)[1].strip() for line in open(driver.log_path)
                  if 'cycle thread: ' in line]
    return {'variant': name, 'driver_parameters': params, 'churn_processes': churn,
            'trials': trials, 'setpoints_on_the_wire': len(times),
            'period_error_ms': stats(np.abs(np.diff(times) - CYCLE), (50, 99)),
            'cycle_start_error_ms': (stats(np.abs(np.diff(cycles) - CYCLE), (50, 99))
                                     if len(cycles) > 2 else None),
            'jointjog_to_frame_ms': stats(latencies, (50, 95)) if latencies else None,
            'jointjog_to_driver_callback_ms': stats(to_node, (50, 95)) if to_node else None,
            'setpoint_span_ms': stats(spans, (50, 99)) if spans else None,
            'missed_trials': trials - len(latencies),
            'churn_exit_codes': churned.get('exit_codes', []),
            'churn_not_started': churned.get('left', 0),
            'driver_scheduling': scheduling[0] if scheduling else 'not logged',
            'wire_scheduling': wire_scheduling}


def probe_main(argv):
    """Run the driver node, saving the monotonic time of every cycle's start to ``argv[0]``."""
    from mover6_control.hardware import driver as hw_driver
    from mover6_control.nodes.driver import jog_intake, node as driver_node
    times = []
    step = hw_driver.ArmDriver.step

    def timed_step(self, now):
        times.append(time.monotonic())
        return step(self, now)

    jogs = []
    on_jog = jog_intake.JogIntake.on_jog

    def timed_jog(self, msg):
        jogs.append((time.monotonic(), msg.velocities[0] if len(msg.velocities) else 0.0))
        return on_jog(self, msg)

    hw_driver.ArmDriver.step = timed_step
    jog_intake.JogIntake.on_jog = timed_jog
    try:
        driver_node.main(argv[1:])
    finally:
        np.save(argv[0], np.array(times))
        np.save(argv[0].replace('.npy', '_jogs.npy'), np.array(jogs))


def churn_main(argv):
    """Start ``argv[1]`` processes that join and leave on status topic ``argv[0]``; report."""
    import signal
    joining = Churn(argv[0], int(argv[1]), argv[2])
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    while not stop and joining.step():
        time.sleep(0.1)
    joining.stop()
    print(json.dumps({'exit_codes': joining.exit_codes, 'left': joining.left}), flush=True)


def main(argv):
    """Run the benchmark; return the exit code."""
    if argv[:1] == ['--probe']:
        probe_main(argv[1:])
        return 0
    if argv[:1] == ['--wire']:
        wire_main(argv[1:])
        return 0
    if argv[:1] == ['--churn']:
        churn_main(argv[1:])
        return 0
    quick = '--quick' in argv
    trials = 8 if quick else 30
    chosen = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == '--variant']
    variants = [v for v in VARIANTS if not chosen or v[0] in chosen]
    tmp = tempfile.mkdtemp(prefix='bench_driver_')
    load = os.getloadavg()[0]
    print(f'load average {load:.2f} on {os.cpu_count()} CPUs; driver cycle {CYCLE * 1e3:.0f} ms; '
          f'logs in {tmp}')
    rows = []
    for name, params, churn in variants:
        row = run_variant(name, params, churn // 4 if quick and churn else churn, trials, tmp)
        if row is None:
            return 1
        rows.append(row)
    print(f'{"[ms]":34s} {"p50":>7s} {"p99/p95":>8s} {"max":>8s}')
    for row in rows:
        print(f'{row["variant"]} ({row["churn_processes"]} joining; driver: '
              f'{row["driver_scheduling"]})')
        for key, label in (('period_error_ms', 'period error on the wire'),
                           ('cycle_start_error_ms', 'cycle start error (in the driver)'),
                           ('jointjog_to_frame_ms', 'JointJog-to-frame'),
                           ('jointjog_to_driver_callback_ms', 'JointJog-to-driver callback'),
                           ('setpoint_span_ms', "a cycle's six set-points, first to last")):
            figures = row[key]
            if figures:
                high = figures.get('p99', figures.get('p95'))
                print(f'  {label:32s} {figures["p50"]:7.2f} {high:8.2f} {figures["max"]:8.2f}'
                      f'  (n {figures["n"]})')
    write_json('driver', {'cycle': CYCLE, 'load_average_1min_at_start': load,
                          'cpus': os.cpu_count(), 'quick': quick, 'variants': rows})
    return 0 if all(r['jointjog_to_frame_ms'] for r in rows) else 1


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
