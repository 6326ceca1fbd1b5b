"""
The controller's tick while a large FollowJointTrajectory goal is taken.

A 10,000-point goal (smooth, inside the limits, untimed) is received, converted and planned for
seconds; none of that may hold up the tick. The sim bridge and the controller start as processes
(their config files, a namespace of their own); this process sends ``--goals`` such goals to
``controller/follow_joint_trajectory`` one after another and reads /JointJog meanwhile. The
figures per goal, from the /JointJog header stamps (the tick's start on the node clock):

- ``taking``: from the send until the controller's status names the goal (received, converted,
  checked and planned): the largest gap between two ticks [ms], the ticks later than 20 ms, and
  the period error p99 |period - 10 ms| [ms];
- ``whole``: the same from the send to the result;
- the goal's duration from send to commit [s], its result, and the controller's own
  ``max_tick_gap`` and ``max_states_age`` (status: the oldest valid /joint_states a tick found,
  how long their intake was held up; 0.25 s faults) at the end, both since the node started;
- ``faults``: the controller's statuses in fault from the send to the result (each once, with
  its message: '/joint_states stale' was the tick's own starvation).

``--watchdog S`` sets ``MOVER6_TICK_WATCHDOG`` in the controller: a tick later than S dumps every
thread's stack to its log (printed at the end: what held the tick up). The load average is
printed and stored. Run: ``./run.sh bench large_goal [--quick] [--points N] [--goals N]``
(``--quick``: 1 goal); writes bench/results/large_goal.json.
"""

import argparse
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
RATE = 100.0                 # [Hz] config/controller.yaml
LATE = 0.020                 # [s] a tick gap counted as late


def smooth(n, amplitude=0.3):
    """Return ``n`` waypoints (n, 6) of a smooth excursion inside the limits, back to home."""
    s = np.sin(np.pi * np.linspace(0.0, 1.0, n))[:, None]
    return amplitude * s * np.array([1.0, -0.5, 0.5, 0.3, 0.4, -0.4])


def gap_figures(stamps):
    """Return the tick figures of the /JointJog stamps [s] received in a window."""
    t = np.sort(np.asarray(stamps))
    if len(t) < 2:
        return {'ticks': int(len(t))}
    gaps = np.diff(t)
    return {'ticks': int(len(t)), 'largest_gap_ms': float(gaps.max() * 1e3),
            'late_ticks': int(np.sum(gaps > LATE)),
            'period_error_p99_ms': float(np.percentile(np.abs(gaps - 1.0 / RATE), 99) * 1e3)}


class Probe:
    """The bench's node: the action client, /JointJog stamps, the controller's status."""

    def __init__(self, namespace):
        """Create the node in its own context."""
        from control_msgs.action import FollowJointTrajectory
        from control_msgs.msg import JointJog
        from diagnostic_msgs.msg import DiagnosticStatus
        from mover6_control.nodes.messages import conversions
        from mover6_control.nodes.runtime.qos import STATUS_QOS
        import rclpy
        from rclpy.action import ActionClient
        from rclpy.executors import SingleThreadedExecutor

        self.rclpy, self.conversions = rclpy, conversions
        self.FollowJointTrajectory = FollowJointTrajectory
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('bench_large_goal', namespace=namespace,
                                      context=self.context)
        self.status = {}
        self.stamps = []
        self.faults = []         # the messages of statuses in fault
        self.node.create_subscription(DiagnosticStatus, 'controller/status', self.on_status,
                                      STATUS_QOS)
        self.node.create_subscription(
            JointJog, 'JointJog',
            lambda m: self.stamps.append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9),
            100)
        self.action = ActionClient(self.node, FollowJointTrajectory,
                                   'controller/follow_joint_trajectory')
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def on_status(self, msg):
        """Keep the latest status values; note a status in fault."""
        self.status.update(self.conversions.status_values(msg))
        if self.status.get('state') == 'fault' and msg.message not in self.faults:
            self.faults.append(msg.message)

    def spin_until(self, predicate, timeout):
        """Spin until ``predicate()`` holds or ``timeout`` [s] passed; return it."""
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
        return predicate()

    def goal(self, rows):
        """Return a FollowJointTrajectory goal through ``rows`` (joint1..joint6), untimed."""
        from trajectory_msgs.msg import JointTrajectoryPoint
        goal = self.FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = [f'joint{i}' for i in range(1, 7)]
        goal.trajectory.points = [JointTrajectoryPoint(positions=[float(v) for v in q])
                                  for q in rows]
        return goal

    def run(self, rows, timeout):
        """Send one goal; return its figures."""
        goal = self.goal(rows)
        sent_ids = int(self.status.get('motion_id', 0))
        self.stamps.clear()
        self.faults.clear()
        t0 = time.monotonic()
        send = self.action.send_goal_async(goal)
        # Taken: the status shows a new motion (the goal committed) or a refusal.
        taken = self.spin_until(lambda: int(self.status.get('motion_id', 0)) > sent_ids
                                or 'rejected' in self.status.get('result', ''), timeout)
        t_taken = time.monotonic() - t0
        taking = gap_figures(self.stamps)
        self.spin_until(send.done, timeout)
        result = None
        if send.done() and send.result().accepted:
            future = send.result().get_result_async()
            self.spin_until(future.done, timeout)
            if future.done():
                r = future.result().result
                result = (r.error_code, r.error_string)
        return {'points': len(rows), 'taken': bool(taken), 'taken_after_s': t_taken,
                'taking': taking, 'whole': gap_figures(self.stamps),
                'whole_s': time.monotonic() - t0,
                'result_code': None if result is None else int(result[0]),
                'result': None if result is None else result[1],
                'max_tick_gap_status_s': float(self.status.get('max_tick_gap', 'nan')),
                'max_states_age_status_s': float(self.status.get('max_states_age', 'nan')),
                'faults': list(self.faults)}

    def close(self):
        """Destroy the node and its context."""
        self.executor.shutdown()
        self.action.destroy()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def run_goals(points, goals, log_dir, watchdog=0.0, timeout=240.0):
    """
    Start the bridge and the controller, send ``goals`` goals of ``points`` points one by one.

    Return ``{'runs': [figures per goal], 'alive_to_the_end': {node: bool},
    'max_tick_gap_before_s': the controller's max_tick_gap before the first goal}``.
    """
    from ros_testing import NodeProcess

    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    namespace = f'bench_large_goal_{os.getpid()}'
    if watchdog > 0.0:
        os.environ['MOVER6_TICK_WATCHDOG'] = str(watchdog)
    nodes = {}
    probe = None
    runs = []
    try:
        for name in ('sim_bridge', 'controller'):
            nodes[name] = NodeProcess(name, log_dir, ros_args=('-r', f'__ns:=/{namespace}'))
        os.environ.pop('MOVER6_TICK_WATCHDOG', None)
        probe = Probe(namespace)
        if not probe.spin_until(lambda: probe.status.get('state') == 'idle'
                                and probe.action.server_is_ready(), 60.0):
            raise RuntimeError('the stack did not come up within 60 s:\n'
                               + '\n'.join(n.tail() for n in nodes.values()))
        before = float(probe.status.get('max_tick_gap', 'nan'))
        states_before = float(probe.status.get('max_states_age', 'nan'))
        rows = smooth(points)
        for i in range(goals):
            run = probe.run(rows, timeout=timeout)
            run['load_average'] = list(os.getloadavg())
            runs.append(run)
            print(run, flush=True)
            probe.spin_until(lambda: probe.status.get('state') == 'idle', 30.0)
        alive = {name: n.alive() for name, n in nodes.items()}
    finally:
        if probe is not None:
            probe.close()
        for n in reversed(list(nodes.values())):   # the controller first: no stale fault
            n.stop()
    return {'runs': runs, 'alive_to_the_end': alive, 'max_tick_gap_before_s': before,
            'max_states_age_before_s': states_before}


def main(argv=None):
    """Start the bridge and the controller, send the goals; print, write large_goal.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='one goal')
    parser.add_argument('--points', type=int, default=10000)
    parser.add_argument('--goals', type=int, default=3)
    parser.add_argument('--repeat', type=int, default=1, help='(ignored: goals)')
    parser.add_argument('--watchdog', type=float, default=0.0,
                        help='MOVER6_TICK_WATCHDOG of the controller [s] (0: off)')
    args = parser.parse_args(argv)
    goals = 1 if args.quick else args.goals
    log_dir = tempfile.mkdtemp(prefix='bench_large_goal_')
    load = os.getloadavg()
    print(f'load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs; '
          f'logs in {log_dir}', flush=True)
    result = run_goals(args.points, goals, log_dir, args.watchdog)
    runs, alive = result['runs'], result['alive_to_the_end']
    print(f'\n{args.points}-point FollowJointTrajectory goals; tick gaps from the /JointJog '
          f'stamps (period {1e3 / RATE:g} ms), late = gap > {LATE * 1e3:g} ms; the '
          f"controller's max_tick_gap before the first goal "
          f'{result["max_tick_gap_before_s"] * 1e3:.1f} ms, max_states_age '
          f'{result["max_states_age_before_s"] * 1e3:.1f} ms')
    print(f'{"goal":>4} {"taken [s]":>9} {"largest gap taking":>18} {"late":>5} '
          f'{"p99 err":>8} {"largest gap whole":>17} {"late":>5} {"status max gap":>14} '
          f'{"states age":>10} {"result":>7} {"faults":>6} {"load":>5}')
    for i, run in enumerate(runs):
        a, b = run['taking'], run['whole']
        print(f'{i + 1:>4} {run["taken_after_s"]:9.2f} {a.get("largest_gap_ms", 0):15.1f} ms '
              f'{a.get("late_ticks", 0):5d} {a.get("period_error_p99_ms", 0):8.2f} '
              f'{b.get("largest_gap_ms", 0):14.1f} ms {b.get("late_ticks", 0):5d} '
              f'{run["max_tick_gap_status_s"] * 1e3:11.1f} ms '
              f'{run["max_states_age_status_s"] * 1e3:7.1f} ms {str(run["result_code"]):>7} '
              f'{len(run["faults"]):6d} {run["load_average"][0]:5.2f}')
    for i, run in enumerate(runs):
        for message in run['faults']:
            print(f'goal {i + 1}: fault: {message}')
    if args.watchdog > 0.0:
        with open(os.path.join(log_dir, 'controller.log')) as f:
            text = f.read()
        print(f'\ncontroller log (watchdog {args.watchdog:g} s):\n{text[-20000:]}')
    write_json('large_goal', {'points': args.points, 'goals': goals, 'cpus': os.cpu_count(),
                              'load_average_at_start': list(load), 'runs': runs,
                              'alive_to_the_end': alive,
                              'max_tick_gap_before_s': result['max_tick_gap_before_s'],
                              'max_states_age_before_s': result['max_states_age_before_s']})
    return 0 if all(alive.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
