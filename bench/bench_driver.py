"""
Timing of the real-arm driver (issue 23): its cycle on the wire, and JointJog-to-frame latency.

Set-up: the driver node in its own process, on the CPR USB2CAN framing over a pty, exactly as on
``/dev/ttyUSB0``; behind the pty, in this process, the CAN-level Mover6 (``sim_bridge.can_sim``:
six simulated modules on the MuJoCo arm), which timestamps every frame it decodes. This process
also plays the controller: it publishes /JointJog at 100 Hz, as the controller node does (the
controller and the planner themselves do not run here).

- Cycle period error [ms]: the time between two consecutive set-point frames of joint 1 as they
  arrive at the modules, minus the driver's ``cycle`` (50 ms): p50, p99, max of its magnitude,
  from the end of the start-up (reset, enable) to the end of the trials.
- JointJog-to-frame latency [ms]: from the publication of the first non-zero JointJog (the arm at
  rest before) to the arrival of the first set-point frame of joint 1 that moves: DDS, the wait
  for the driver's next cycle (0 to one cycle by design), the serial write and the pty. p50, p95,
  max over the trials.

Run: ``python -m bench.bench_driver [--quick]`` (``./run.sh bench driver``); writes
bench/results/driver.json.
"""

import os
import sys
import tempfile
import threading
import time

from bench.output import write_json
from bench.processes import NodeProcess
from control_msgs.msg import JointJog
from mover6_control.hardware import protocol
from mover6_control.nodes.conversions import make_joint_jog
import numpy as np
import rclpy
from sim_bridge.can_sim import build_arm, SerialArm
from std_srvs.srv import Trigger

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NAMES = [f'joint{i}' for i in range(1, 7)]
CYCLE = 0.05


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
        self.thread = threading.Thread(target=self.server.run, daemon=True)

    def joint1(self, since=0.0):
        with self.lock:
            return [(t, pos) for t, j, pos in self.setpoints if j == 1 and t >= since]


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


def stats(values, quantiles):
    """Return the named quantiles and the max of ``values`` [ms]."""
    arr = np.asarray(values) * 1e3
    out = {f'p{q}': round(float(np.percentile(arr, q)), 2) for q in quantiles}
    out['max'] = round(float(arr.max()), 2)
    out['n'] = int(arr.size)
    return out


def main(argv):
    """Run the benchmark; return the exit code."""
    quick = '--quick' in argv
    trials = 8 if quick else 30
    tmp = tempfile.mkdtemp(prefix='bench_driver_')
    link = os.path.join(tmp, 'mover6-can')
    wire = Wire(link)
    wire.thread.start()
    namespace = f'bench_driver_{os.getpid()}'
    driver = NodeProcess(
        [sys.executable, '-m', 'mover6_control.nodes.driver_node', '--ros-args', '-r',
         f'__ns:=/{namespace}', '-p', 'can_interface:=cpr_usb2can', '-p',
         f'can_channel:={link}'], os.path.join(tmp, 'driver.log'), ROOT)
    rclpy.init()
    node = rclpy.create_node('bench_driver', namespace=namespace)
    pub = node.create_publisher(JointJog, 'JointJog', 10)
    clients = {k: node.create_client(Trigger, f'driver/{k}') for k in ('reset', 'enable')}
    try:
        for kind in ('reset', 'enable'):
            ok, message = call(node, clients[kind])
            if not ok:
                print(f'{kind} failed: {message}\n{driver.tail()}', file=sys.stderr)
                return 1
        latencies = []
        t_start = time.monotonic()                   # the driver runs: measure from here
        for _ in range(trials):
            jog_for(node, pub, 0.0, 0.4)             # at rest, set-points steady
            t_pub = jog_for(node, pub, 0.2, 0.15)
            jog_for(node, pub, 0.0, 0.1)
            frames = wire.joint1(since=t_pub - 0.2)
            before = [pos for t, pos in frames if t < t_pub]
            moved = [t for t, pos in frames if t >= t_pub and before and pos != before[-1]]
            if moved:
                latencies.append(moved[0] - t_pub)
        times = [t for t, _ in wire.joint1(since=t_start)]
        errors = np.abs(np.diff(times) - CYCLE)
        result = {'cycle': CYCLE, 'trials': trials,
                  'period_error_ms': stats(errors, (50, 99)),
                  'jointjog_to_frame_ms': stats(latencies, (50, 95)) if latencies else None,
                  'missed_trials': trials - len(latencies)}
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        driver.stop()
        wire.server.running = False
        wire.thread.join(timeout=10.0)
        wire.server.close()
    print(f'driver cycle {CYCLE * 1e3:.0f} ms, {len(times)} set-points of joint 1 on the wire')
    print(f'{"":28s} {"p50":>8s} {"p99/p95":>8s} {"max":>8s}')
    pe = result['period_error_ms']
    print(f'{"cycle period error [ms]":28s} {pe["p50"]:8.2f} {pe["p99"]:8.2f} {pe["max"]:8.2f}')
    lat = result['jointjog_to_frame_ms']
    if lat:
        print(f'{"JointJog-to-frame [ms]":28s} {lat["p50"]:8.2f} {lat["p95"]:8.2f} '
              f'{lat["max"]:8.2f}  ({lat["n"]} of {trials} trials)')
    write_json('driver', result)
    return 0 if lat else 1


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
