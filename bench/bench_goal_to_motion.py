"""
A 1000-waypoint linear pose goal through the running nodes: goal published to 'executing'.

The sim bridge, the controller and the planner start as processes over
DDS (their config files, the package's loopback-only DDS profile, a namespace of their own); the
planner's ``n_waypoints`` is 1000, its ``motion`` linear. This process publishes /pose_goal
and measures the time from the publish to the first /controller/status that says 'executing'
with a new motion (the controller took the plan: received, converted, timed, committed). One
warm-up goal from home, then ``--goals`` goals alternating between the planner bench's two poses
(each a real motion of the simulated arm, waited to its end before the next goal). In the same
run, toppra (a bench requirement) times the same 1000 waypoints per goal (the planner's plan from
the joint positions the goal started at, computed here) as ``bench motion``'s
``linear_goal_1000`` calls it: a cubic spline with toppra's own grid, the Mover6 speed limits and
1 rad/s^2; the ratio is ours end to end over toppra's timing alone (the issue's goal: at most 10).

Where the time goes: this process also hears /joint_demands, so each goal's latency splits into
the planner's part (the publish to the goal's demand arriving here, as at the controller) and
the controller's (that demand to 'executing'); and after the run, in this process, the stages'
CPU time on the second goal's plan (medians of 7: the plan's path IK and collision check, the
demand message both ways, the controller's timing law, its collision guard, the pickling to
and from its plan worker). Both go into the JSON (``stages``).
Run: ``./run.sh bench goal_to_motion [--quick] [--goals N]``; writes
bench/results/goal_to_motion.json (with the load average).
"""

import argparse
import os
import pickle
import sys
import tempfile
import time

from bench import peer_toppra
from bench.output import write_json
from mover6_control.nodes.runtime import local_dds
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, 'test'))
WAYPOINTS = 1000
A_MAX = 1.0          # [rad/s^2] as bench_motion's linear_goal_1000
GOAL = 10.0          # the goal: at most 10x toppra's timing alone


def poses():
    """Return the planner bench's two goal poses, each (4, 4)."""
    from mover6_control.kinematics.rotations import pose_from_xyzabc
    return (pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0),
            pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0))


class Probe:
    """The bench's node: publishes pose goals, keeps /controller/status and /joint_states."""

    def __init__(self, namespace):
        """Create the goal client in ``namespace`` (rclpy initialised here)."""
        from diagnostic_msgs.msg import DiagnosticStatus
        from mover6_control.nodes.messages import conversions
        from mover6_control.tools.goal_cli import GoalClient
        import rclpy
        from rclpy.qos import DurabilityPolicy, QoSProfile

        self.rclpy, self.conversions = rclpy, conversions
        rclpy.init(args=['--ros-args', '-r', f'__ns:=/{namespace}'])
        self.client = GoalClient(name='bench_goal_to_motion')
        self.executing = []      # (perf_counter, motion_id) of each status saying 'executing'
        self.demands = []        # (perf_counter, goal id) of each /joint_demands heard
        self.status = {}
        qos = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.client.create_subscription(DiagnosticStatus, 'controller/status', self.on_status,
                                        qos)
        from mover6_control.nodes.messages.demand_messages import demand_id_from_msg
        from std_msgs.msg import Float32MultiArray
        self.demand_id = demand_id_from_msg
        self.client.create_subscription(Float32MultiArray, 'joint_demands', self.on_demand, 10)

    def on_demand(self, msg):
        """Note when a demand arrives, with its goal id."""
        self.demands.append((time.perf_counter(), self.demand_id(msg)))

    def on_status(self, msg):
        """Note when a status says 'executing', with its motion id."""
        values = self.conversions.status_values(msg)
        self.status = values
        if values.get('state') == 'executing':
            self.executing.append((time.perf_counter(), int(values.get('motion_id', 0))))

    def motion_id(self):
        """Return the controller's latest motion id (0 before any)."""
        return int(self.status.get('motion_id', 0))

    def goal(self, T_goal, timeout=20.0):
        """
        Publish one pose goal; return (seconds to 'executing', q at the publish, to demand).

        The last: seconds from the publish to the goal's demand arriving here.

        Waits for the motion's end (the controller idle again with a result) before returning.
        """
        from geometry_msgs.msg import PoseStamped
        client = self.client
        before = self.motion_id()
        q_start = np.array(client.q, dtype=float)
        msg = PoseStamped()
        msg.header.frame_id = 'base_link'
        msg.pose = self.conversions.matrix_to_pose(T_goal)
        self.executing.clear()
        self.demands.clear()
        t0 = time.perf_counter()
        client.pose_pub.publish(msg)
        if not client.spin_until(lambda: any(m > before for _, m in self.executing), timeout):
            raise RuntimeError(f'no executing status within {timeout} s: planner '
                               f'{client.values(client.planner_status)}, controller '
                               f'{self.status}')
        started = next(t for t, m in self.executing if m > before)
        # The goal's demand (the planner sends it again until the controller answers).
        demand = min((t for t, _ in self.demands), default=float('nan'))
        motion = next(m for _, m in self.executing if m > before)
        if not client.spin_until(lambda: self.status.get('state') == 'idle'
                                 and self.motion_id() == motion
                                 and self.status.get('result') == 'arrived', 60.0):
            raise RuntimeError(f'motion {motion} did not arrive: {self.status}')
        # The planner's 'planned' (its prediction, after the demand) before the next goal.
        client.spin_until(lambda: client.values(client.planner_status).get('result')
                          == 'planned', 10.0)
        return started - t0, q_start, demand - t0

    def close(self):
        """Destroy the node; shut rclpy down."""
        self.client.destroy_node()
        self.rclpy.try_shutdown()


def toppra_times(starts_goals, repeats):
    """
    Return toppra's timing [s] (median of ``repeats``) of each goal's 1000 waypoints.

    The planner's plan (``plan_pose_goal``, linear, 1000 waypoints, its default settings else)
    from each goal's start joint positions; toppra on a spline through it, its own grid.
    """
    from mover6_control.kinematics.arm import mover6
    from mover6_control.planning.planner_core import PlannerSettings, plan_pose_goal
    arm = mover6()
    v, a = arm.velocity_limits, np.full(arm.n_joints, A_MAX)
    out = []
    for q_start, T_goal in starts_goals:
        Q = np.asarray(plan_pose_goal(arm, q_start, T_goal, 'linear',
                                      PlannerSettings(n_waypoints=WAYPOINTS)).q)
        _, t_peer, _ = peer_toppra.timed(peer_toppra.spline(Q, v, a), repeats)
        out.append(t_peer)
    return out


def median_ms(fn, repeats=7):
    """Return the median wall time [ms] of ``fn()`` over ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def stage_times(q_start, T_goal):
    """
    Return the CPU stages [ms] of one goal's way, in this process (medians of 7).

    The planner's plan (``plan_pose_goal``) with its path IK (``_solve``) and collision check
    (``check_plan_collision``) timed inside it, the demand message made and read, the
    controller's job (``PlanJob.run``: the timing law) without and with its collision guard,
    and the pickling of the job and the plan to and from the plan worker.
    """
    from mover6_control.control.collision_guard import CollisionGuard
    from mover6_control.control.demand_intake import PlanJob
    from mover6_control.control.profiles import LawConfig
    from mover6_control.kinematics.arm import mover6
    from mover6_control.nodes.messages import demand_messages
    from mover6_control.planning import planner_core
    arm = mover6()
    settings = planner_core.PlannerSettings(n_waypoints=WAYPOINTS)
    checker = planner_core.make_checker(arm, settings)
    inner = {'_solve': [], 'check_plan_collision': []}
    originals = {name: getattr(planner_core, name) for name in inner}

    def timed(name):
        def call(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return originals[name](*args, **kwargs)
            finally:
                inner[name].append(time.perf_counter() - t0)
        return call
    for name in inner:
        setattr(planner_core, name, timed(name))
    try:
        plan_ms = median_ms(lambda: planner_core.plan_pose_goal(arm, q_start, T_goal, 'linear',
                                                                settings, checker))
    finally:
        for name, fn in originals.items():
            setattr(planner_core, name, fn)
    plan = planner_core.plan_pose_goal(arm, q_start, T_goal, 'linear', settings, checker)
    msg = demand_messages.make_demands(plan.q, 'g', '')
    job = PlanJob(LawConfig(), q_start, demand_messages.demands_from_msg(msg, arm.n_joints),
                  arm.velocity_limits, None, None, arm.lower, arm.upper)
    guard = CollisionGuard(arm)
    motion = job.run(None)
    return {
        'plan_ms': plan_ms,
        'plan_path_ik_ms': float(np.median(inner['_solve']) * 1e3),
        'plan_collision_ms': float(np.median(inner['check_plan_collision']) * 1e3),
        'make_demands_ms': median_ms(lambda: demand_messages.make_demands(plan.q, 'g', '')),
        'demands_from_msg_ms': median_ms(
            lambda: demand_messages.demands_from_msg(msg, arm.n_joints)),
        'controller_law_ms': median_ms(lambda: job.run(None)),
        'controller_guard_ms': median_ms(lambda: guard(motion[0])),
        'worker_pickles_ms': (
            median_ms(lambda: pickle.loads(pickle.dumps((job, guard), pickle.HIGHEST_PROTOCOL)))
            + median_ms(lambda: pickle.loads(pickle.dumps(('plan', motion),
                                                          pickle.HIGHEST_PROTOCOL)))),
        'law_profile': LawConfig().profile, 'waypoints': int(len(plan.q))}


def main(argv=None):
    """Start the stack, send the goals, time toppra; print, write goal_to_motion.json."""
    from ros_testing import Stack
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='4 goals')
    parser.add_argument('--goals', type=int, default=14)
    parser.add_argument('--repeat', type=int, default=1, help='(ignored)')
    args = parser.parse_args(argv)
    goals = 4 if args.quick else args.goals
    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    log_dir = tempfile.mkdtemp(prefix='bench_goal_to_motion_')
    namespace = f'bench_goal_to_motion_{os.getpid()}'
    load_start = os.getloadavg()
    print(f'load average {load_start[0]:.2f} {load_start[1]:.2f} {load_start[2]:.2f} on '
          f'{os.cpu_count()} CPUs; logs in {log_dir}', flush=True)
    A, B = poses()
    latencies, starts_goals, to_demand = [], [], []
    probe = None
    stack = Stack(log_dir, planner={'n_waypoints': WAYPOINTS, 'motion': 'linear'},
                  ros_args={name: ('-r', f'__ns:=/{namespace}')
                            for name in ('sim_bridge', 'controller', 'planner')})
    try:
        stack.__enter__()
        probe = Probe(namespace)
        problem = probe.client.wait_ready(timeout=60.0)
        if problem is not None:
            raise RuntimeError(f'{problem}\n{stack.report()}')
        probe.goal(A)                     # warm-up from home, not counted
        for i in range(goals):
            T_goal = B if i % 2 == 0 else A
            seconds, q_start, demand = probe.goal(T_goal)
            latencies.append(seconds)
            to_demand.append(demand)
            starts_goals.append((q_start, T_goal))
            print(f'goal {i + 1}: {seconds * 1e3:.1f} ms (demand at {demand * 1e3:.1f} ms)',
                  flush=True)
    finally:
        if probe is not None:
            probe.close()
        stack.stop_all()
    load_goals = os.getloadavg()
    peer = np.array(toppra_times(starts_goals[:2], 1 if args.quick else 5)) * 1e3
    lat = np.array(latencies) * 1e3
    median, p95 = float(np.median(lat)), float(np.percentile(lat, 95))
    peer_ms = float(np.median(peer))
    demand = np.array(to_demand) * 1e3
    stages = {'goal_to_demand_ms': demand.tolist(),
              'demand_to_executing_ms': (lat - demand).tolist(),
              'goal_to_demand_median_ms': float(np.nanmedian(demand)),
              'demand_to_executing_median_ms': float(np.nanmedian(lat - demand)),
              'in_process': stage_times(*starts_goals[1 % len(starts_goals)])}
    ratio = median / peer_ms
    print(f'\n{WAYPOINTS}-waypoint linear goals through sim_bridge, controller, planner over '
          f'DDS, /pose_goal published to the controller executing, {goals} goals')
    print(f'median {median:.1f} ms, p95 {p95:.1f} ms, max {lat.max():.1f} ms; toppra alone on '
          f'the same waypoints {peer_ms:.1f} ms (per direction: '
          f'{", ".join(f"{p:.1f}" for p in peer)} ms); ours / toppra {ratio:.1f}x (median), '
          f'{p95 / peer_ms:.1f}x (p95); goal <= {GOAL:g}x: {"met" if ratio <= GOAL else "MISSED"}')
    print(f'planner (publish to the demand here) median {stages["goal_to_demand_median_ms"]:.1f}'
          f' ms, controller (demand to executing) {stages["demand_to_executing_median_ms"]:.1f}'
          ' ms; in this process [ms]: ' + ', '.join(
              f'{k[:-3]} {v:.1f}' for k, v in stages['in_process'].items() if k.endswith('_ms')))
    print(f'load average at the end of the goals {load_goals[0]:.2f} {load_goals[1]:.2f} '
          f'{load_goals[2]:.2f}')
    write_json('goal_to_motion', {
        'waypoints': WAYPOINTS, 'goals': goals, 'cpus': os.cpu_count(),
        'load_average_at_start': list(load_start), 'load_average_after_goals': list(load_goals),
        'latencies_ms': lat.tolist(), 'median_ms': median, 'p95_ms': p95,
        'max_ms': float(lat.max()), 'toppra_ms_per_direction': peer.tolist(),
        'toppra_ms': peer_ms, 'ratio_median': ratio, 'ratio_p95': p95 / peer_ms,
        'goal_ratio': GOAL, 'goal_met': ratio <= GOAL, 'stages': stages})
    return 0


if __name__ == '__main__':
    sys.exit(main())
