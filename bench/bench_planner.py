"""
Goal-to-/joint_demands latency of the planner node over DDS.

Starts the planner as its own process, publishes /joint_states (home pose) from this process,
sends /pose_goal linear goals and measures the time from publishing the goal to receiving the
N x 6 /joint_demands, for 20, 100 and 1000 waypoints. Each goal goes to an idle planner: after
the planner's 'planned' for the one before. No controller runs: this process stands in for
one on the graph (a publisher of its demand answers, which never answers), as the planner sends
a demand only once a controller is there (else after ``match_timeout``, 3 s). Prints a table,
writes bench/results/planner.json.
"""

import argparse
import tempfile
import time

from actionlib_msgs.msg import GoalStatus
from bench.output import write_json
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.nodes.messages import conversions
from mover6_control.nodes.messages.demand_acks import ACK_QOS, ACK_TOPIC
from mover6_control.nodes.messages.demand_messages import demand_options_from_msg
from mover6_control.tools.goal_cli import GoalClient
import numpy as np
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from ros_testing import NodeProcess
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32MultiArray

STATUS_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
GOALS = (pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0),
         pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0))


def measure(client, n_waypoints, repeats, seen):
    """
    Return latencies [s] from goal publish to /joint_demands arrival.

    ``seen``: the goal ids whose demand arrived already (kept from size to size).
    """
    problem = client.set_planner_parameters({'n_waypoints': n_waypoints})
    if problem:
        raise RuntimeError(problem)
    received, ids, answered = [], [], set()

    def on_demand(msg):
        # The planner sends a goal's demand again until a controller acknowledges it (none
        # runs here): count only the first arrival of each goal's demand.
        goal = demand_options_from_msg(msg).get('goal')
        if goal not in seen:
            seen.add(goal)
            received.append(time.perf_counter())
            ids.append(goal)

    def on_status(msg):
        values = conversions.status_values(msg)
        if values.get('result') == 'planned':
            answered.add(values.get('goal_id'))

    sub = client.create_subscription(Float32MultiArray, 'joint_demands', on_demand, 10)
    status_sub = client.create_subscription(DiagnosticStatus, 'planner/status', on_status,
                                            STATUS_QOS)
    latencies = []
    for i in range(repeats):
        received.clear()
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.pose = conversions.matrix_to_pose(GOALS[i % 2])
        t0 = time.perf_counter()
        client.pose_pub.publish(msg)
        if not client.spin_until(lambda: bool(received), 10.0):
            raise RuntimeError(f'no /joint_demands for {n_waypoints} waypoints')
        latencies.append(received[0] - t0)
        # The next goal goes to an idle planner: after this one's answer ('planned' with the
        # predicted duration, which the planner may say after the demand is out).
        if not client.spin_until(lambda: ids[0] in answered, 10.0):
            raise RuntimeError(f'no planned status for goal {ids[0]}')
        ids.clear()
    client.destroy_subscription(sub)
    client.destroy_subscription(status_sub)
    return latencies


def main(argv=None):
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer repeats')
    args = parser.parse_args(argv)
    repeats = 10 if args.quick else 50
    arm = mover6()
    log_dir = tempfile.mkdtemp(prefix='bench_planner_')
    planner = NodeProcess('planner', log_dir)
    rclpy.init()
    client = GoalClient(name='bench_planner')
    state_pub = client.create_publisher(JointState, 'joint_states', 10)
    home = conversions.make_joint_state(arm.joint_names, np.zeros(6), np.zeros(6))
    client.create_timer(0.01, lambda: state_pub.publish(home))
    # A controller on the graph for the planner (it waits for one before it sends a demand).
    client.create_publisher(GoalStatus, ACK_TOPIC, ACK_QOS)
    results = {'repeats': repeats, 'rows': []}
    seen = set()
    try:
        if not client.spin_until(lambda: client.planner_status is not None
                                 and client.pose_pub.get_subscription_count() > 0, 30.0):
            raise RuntimeError('planner did not come up:\n' + planner.tail())
        client.spin_until(lambda: False, 0.5)   # let /joint_states reach the planner
        print(f'{"waypoints":>10} {"median [ms]":>12} {"p95 [ms]":>10} {"max [ms]":>10}')
        for n in (20, 100, 1000):
            lat = np.array(measure(client, n, repeats, seen)) * 1e3
            row = {'waypoints': n, 'median_ms': float(np.median(lat)),
                   'p95_ms': float(np.percentile(lat, 95)), 'max_ms': float(lat.max())}
            results['rows'].append(row)
            print(f'{n:>10} {row["median_ms"]:>12.2f} {row["p95_ms"]:>10.2f} '
                  f'{row["max_ms"]:>10.2f}')
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
        planner.stop()
    # The goals: p95 under 10 ms at 100 waypoints and under 60 ms at 1000.
    p95 = {r['waypoints']: r['p95_ms'] for r in results['rows']}
    results['goal_p95_100_waypoints_ms'] = 10.0
    results['goal_p95_1000_waypoints_ms'] = 60.0
    results['goal_met'] = p95[100] < 10.0 and p95[1000] < 60.0
    print(f'goal: p95 under 10 / 60 ms at 100 / 1000 waypoints: '
          f'{"met" if results["goal_met"] else "MISSED"} ({p95[100]:.2f} / {p95[1000]:.2f} ms)')
    write_json('planner', results)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
