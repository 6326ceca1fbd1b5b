"""
The controller profiles in simulation on the Mover6 report's linear example.

"For the Mover6 report's linear example in simulation, per profile: time to arrive, final joint
error, largest Cartesian deviation from the straight line."

The Mover6 report's example: from home (q = 0, flange at (0.345, 0, 0.4425) m) to X = 0.445, Y = 0,
Z = 0.4425 [m] with A = B = C = 0 composed relative to the home orientation
(``R_goal = R_home @ Rzyx(0, 0, 0)``: the home orientation kept), a straight line in 20
waypoints (the planner's ``n_waypoints``). The goal is checked offline first
(``reachability.check_pose``, ``planner_core.plan_pose_goal``); should it be refused, the same
straight line is shortened, then other directions from home are tried, and the output and JSON
say which variant ran.

Per profile (every one of the controller's ``profile`` values) the three nodes start as
processes (``testing.Stack``: sim_bridge in real time, controller with ``profile:=<p>``,
planner), a ``GoalClient`` in this process publishes the goal and records /joint_states and
/controller/status with their arrival times. Figures:

- arrive [s]: from publishing the goal to the controller's status saying ``arrived`` (planning
  and settling into the goal tolerance included); plan [s] is the planner's share, ref end [s]
  when the controller's reference ended (status ``settling``); the rest is settling.
- final joint error [mrad]: the largest joint's distance from the last demanded waypoint, on
  the first /joint_states after arrival.
- line deviation [mm]: ``metrics.max_deviation_from_polyline`` of FK(q(t)) for every recorded
  /joint_states between goal and arrival against the straight line from the start to the goal;
  orientation deviation [deg]: the largest angle away from the (constant) goal orientation.
- predicted [s]: the planner's announced duration; ref [s] the duration of the controller's
  reference (``plots.profile_metrics``: the same plan from the recorded start through the
  demanded waypoints), with its peak jerk [rad/s^3] (differences of the velocity every 1 ms).

A run that fails (nodes not ready, goal not arriving, or the controller not taking the
planner's demand within ``DEMAND_WAIT``: seen now and then with the continuous profile, see
``failed_attempts`` in the JSON) is started afresh with a new stack, up to ``ATTEMPTS`` times.

Run: ``./run.sh exec python -m bench.bench_profiles [--quick]`` (``--quick``: one run per
profile, about a minute; otherwise three). A plain ``.venv/bin/python -m bench.bench_profiles``
re-runs itself through ``run.sh exec`` when the ROS messages of the nodes are not importable.
Writes bench/results/profiles.json. ROS traffic stays on localhost in ``ROS_DOMAIN_ID`` (one
is picked when unset).
"""

import argparse
import importlib.util
import json
import os
import random
import sys
import tempfile
import time

from bench.output import write_json
from mover6_control.nodes.runtime import local_dds
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Every controller profile (the parameter table's allowed values: only the base layer is imported
# before the re-exec into the ROS environment).
PROFILES = ('synchronised', 'trapezoidal', 'jerk_limited', 'continuous', 'cubic', 'quintic',
            'septic', 'sharp_trapezoid', 'cubic_spline', 'quintic_spline', 'bspline',
            'multi_trapezoid')
# [m] the Mover6 report's example, A = B = C = 0 relative to home
SEED_GOAL = (0.445, 0.0, 0.4425)
N_WAYPOINTS = 20
MOVED = 1e-3                          # [rad] the arm has started once a joint moved this far
ATTEMPTS = 3                          # a run whose stack fails is started afresh
DEMAND_WAIT = 3.0                     # [s] from the planner's answer to the controller's motion


def goal_variants(p_home):
    """
    Yield (description, position (3,) [m]) for the goal: the Mover6 report's first, then fallbacks.

    Fallbacks: the same straight line along +x shortened, then 0.1 m along other directions.
    """
    yield 'the Mover6 report as given: +0.100 m along base x from home', np.array(SEED_GOAL)
    for length in (0.08, 0.06, 0.04, 0.02):
        yield (f'fallback: the Mover6 report line shortened to +{length:.3f} m along base x',
               p_home + np.array([length, 0.0, 0.0]))
    for axis, step in (('-z', (0.0, 0.0, -0.1)), ('+z', (0.0, 0.0, 0.1)),
                       ('+y', (0.0, 0.1, 0.0))):
        yield f'fallback: 0.100 m along base {axis} from home', p_home + np.array(step)


def choose_goal(arm):
    """Return the goal (4, 4), its description and the offline checks of every candidate."""
    from mover6_control.errors import UnreachableError
    from mover6_control.kinematics.forward import fk
    from mover6_control.kinematics.reachability import check_pose
    from mover6_control.kinematics.rotations import euler_zyx_to_matrix, make_transform
    from mover6_control.planning.planner_core import plan_pose_goal, PlannerSettings

    q_home = np.zeros(arm.n_joints)
    T_home = fk(arm, q_home)
    R_goal = T_home[:3, :3] @ euler_zyx_to_matrix(0.0, 0.0, 0.0)
    tried = []
    for text, position in goal_variants(T_home[:3, 3]):
        T_goal = make_transform(position, R_goal)
        verdict = check_pose(arm, T_goal, q_home)
        entry = {'variant': text, 'position': position.tolist(),
                 'reachable': bool(verdict.reachable), 'reason': verdict.reason,
                 'message': verdict.message}
        if verdict.reachable:
            try:
                plan = plan_pose_goal(arm, q_home, T_goal, 'linear',
                                      PlannerSettings(n_waypoints=N_WAYPOINTS))
                entry['planned_waypoints'] = plan.n_waypoints
                entry['largest_joint_step'] = float(np.abs(np.diff(plan.q, axis=0)).max())
            except UnreachableError as err:
                entry.update(reachable=False, reason=err.reason, message=f'planning: {err}')
        tried.append(entry)
        if entry['reachable']:
            return T_goal, text, tried
    raise SystemExit('no goal variant is reachable: ' + json.dumps(tried, indent=1))


def make_client():
    """Return a GoalClient that also records /joint_states and /controller/status with times."""
    from mover6_control.tools.goal_cli import GoalClient

    class RecordingClient(GoalClient):
        """GoalClient keeping (monotonic time, q) and (monotonic time, status values)."""

        def __init__(self):
            super().__init__(name='bench_profiles_client')
            self.samples = []
            self.controller_events = []
            self.planner_events = []

        def on_joint_states(self, msg):
            """Keep the joint positions with their arrival time."""
            before = self.q
            super().on_joint_states(msg)
            if self.q is not None and self.q is not before:
                self.samples.append((time.monotonic(), np.array(self.q)))

        def on_controller(self, msg):
            """Keep the controller's status with its arrival time."""
            super().on_controller(msg)
            self.controller_events.append((time.monotonic(), self.values(msg)))

        def on_planner(self, msg):
            """Keep the planner's status with its arrival time."""
            super().on_planner(msg)
            self.planner_events.append((time.monotonic(), self.values(msg)))

    return RecordingClient()


def graph_ready(client):
    """Return True when /joint_demands, /JointJog and /joint_states have both their ends."""
    return (client.count_publishers('joint_demands') >= 2
            and client.count_subscribers('joint_demands') >= 2
            and client.count_publishers('JointJog') >= 1
            and client.count_subscribers('JointJog') >= 1
            and client.count_publishers('joint_states') >= 1)


def run_once(profile, T_goal, log_dir, timeout):
    """Start the stack with ``profile``, send the goal, return the figures of the run."""
    from geometry_msgs.msg import PoseStamped
    from mover6_control.nodes.messages import conversions
    from ros_testing import Stack

    with Stack(log_dir, controller={'profile': profile}, planner={'profile': profile}) as stack:
        client = make_client()
        try:
            problem = client.wait_ready(timeout=60.0)
            if problem:
                raise RuntimeError(f'{profile}: {problem}\n{stack.report()}')
            # The planner publishes the demands once: wait until the graph shows the planner's
            # publisher and the controller's subscription (besides this client's own), and the
            # controller-to-sim link, then a little longer so every match is in place.
            if not client.spin_until(lambda: graph_ready(client), 30.0):
                raise RuntimeError(f'{profile}: the nodes did not find each other within 30 s\n'
                                   f'{stack.report()}')
            n0 = len(client.samples)
            client.spin_until(lambda: len(client.samples) >= n0 + 50, 5.0)
            q_start = client.samples[-1][1]
            motion0 = int(client.values(client.controller_status).get('motion_id', 0))
            seq0 = int(client.values(client.planner_status).get('goal_seq', 0))
            msg = PoseStamped()
            msg.header.frame_id = 'base_link'
            msg.header.stamp = client.get_clock().now().to_msg()
            msg.pose = conversions.matrix_to_pose(T_goal)
            sent = []

            def publish():
                sent.append(time.monotonic())
                client.pose_pub.publish(msg)

            def watchdog(_text):
                # Called about twice a second while run_goal waits for the motion to end.
                planned = [t for t, v in client.planner_events
                           if int(v.get('goal_seq', 0)) > seq0]
                taken = int(client.values(client.controller_status).get('motion_id', 0))
                if planned and taken == motion0 and time.monotonic() - planned[0] > DEMAND_WAIT:
                    raise RuntimeError(
                        f'{profile}: the planner answered but the controller took no demand '
                        f'within {DEMAND_WAIT:.0f} s (state '
                        f'{client.values(client.controller_status).get("state")})\n'
                        f'{stack.report()}')

            outcome = client.run_goal(publish, T_goal=T_goal, timeout=timeout,
                                      progress=watchdog, stamp=msg.header.stamp)
            if not outcome.arrived:
                raise RuntimeError(f'{profile}: {outcome}\n{stack.report()}')
            out = figures(client, outcome, T_goal, q_start, sent[0], motion0, seq0)
            out.update(reference_figures(client, profile, q_start, seq0))
            return out
        finally:
            client.destroy_node()


def figures(client, outcome, T_goal, q_start, t_sent, motion0, seq0):
    """Return the figures of one run from the recorded messages."""
    from mover6_control.kinematics.forward import fk, fk_batch
    from mover6_control.kinematics.rotations import rotation_angle_between
    from mover6_control.motion.metrics import max_deviation_from_polyline

    t_arrived = next(t for t, v in client.controller_events
                     if int(v.get('motion_id', 0)) > motion0 and v.get('result') == 'arrived')
    t_planned = next(t for t, v in client.planner_events if int(v.get('goal_seq', 0)) > seq0)
    settling = [t for t, v in client.controller_events
                if int(v.get('motion_id', 0)) > motion0 and v.get('state') == 'settling']
    t = np.array([s[0] for s in client.samples])
    Q = np.array([s[1] for s in client.samples])
    during = (t >= t_sent) & (t <= t_arrived)
    moved = np.flatnonzero(during & (np.abs(Q - q_start).max(axis=1) > MOVED))
    # The motion: every sample from the goal to the arrival plus the first one after it.
    last = min(int(np.flatnonzero(t <= t_arrived)[-1]) + 1, len(t) - 1)
    first = int(np.flatnonzero(during)[0])
    T = fk_batch(client.arm, Q[first:last + 1])
    line = np.stack([fk(client.arm, q_start)[:3, 3], T_goal[:3, 3]])
    deviation = max_deviation_from_polyline(T[:, :3, 3], line)
    turn = max(rotation_angle_between(Tk[:3, :3], T_goal[:3, :3]) for Tk in T)
    return {
        'arrive_s': float(t_arrived - t_sent),
        'plan_s': float(t_planned - t_sent),
        # Within the tolerance when the reference ends, the controller arrives in that same
        # tick and no 'settling' status goes out: the reference ended on arrival.
        'reference_done_s': float((settling[0] if settling else t_arrived) - t_sent),
        'first_motion_s': float(t[moved[0]] - t_sent) if moved.size else None,
        'final_joint_error_rad': float(outcome.figures['final_joint_error']),
        'final_position_error_m': float(outcome.figures['final_position_error']),
        'max_line_deviation_m': float(deviation),
        'max_orientation_deviation_rad': float(turn),
        'joint_state_samples': int(last + 1 - first),
        'waypoints': int(len(client.last_demands)) if client.last_demands is not None else None,
    }


def reference_figures(client, profile, q_start, seq0):
    """Return the planner's prediction and the duration and peak jerk of the reference."""
    from mover6_control.tools.plots import profile_metrics

    answer = next(v for _, v in client.planner_events if int(v.get('goal_seq', 0)) > seq0)
    ref = profile_metrics(client.arm, profile, q_start, np.asarray(client.last_demands))
    return {'predicted_s': float(answer['predicted_duration']),
            'reference_s': ref['duration'], 'reference_peak_jerk': ref['peak_jerk']}


def summarise(runs):
    """Return the median of every figure over the runs of one profile (and their spread)."""
    keys = [k for k in runs[0] if all(isinstance(r.get(k), float) for r in runs)]
    out = {k: float(np.median([r[k] for r in runs])) for k in keys}
    out['arrive_s_min'] = float(min(r['arrive_s'] for r in runs))
    out['arrive_s_max'] = float(max(r['arrive_s'] for r in runs))
    out['runs'] = len(runs)
    return out


def print_table(goal_text, T_goal, summary):
    """Print one row per profile (medians over the runs)."""
    p = T_goal[:3, 3]
    print(f'goal: {goal_text}; ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m, home orientation kept, '
          f'{N_WAYPOINTS} waypoints, sim in real time')
    head = (f'{"profile":<15} {"runs":>4} {"arrive [s]":>10} {"plan [s]":>8} {"ref end [s]":>11} '
            f'{"predicted [s]":>13} {"ref [s]":>7} {"peak jerk":>10} '
            f'{"joint err [mrad]":>16} {"pos err [mm]":>12} {"line dev [mm]":>13} '
            f'{"orient dev [deg]":>16}')
    print(head)
    print('-' * len(head))
    for name, s in summary.items():
        ref = s.get('reference_done_s')
        ref = f'{ref:>11.2f}' if ref is not None else f'{"-":>11}'
        print(f'{name:<15} {s["runs"]:>4} {s["arrive_s"]:>10.2f} {s["plan_s"]:>8.2f} {ref} '
              f'{s["predicted_s"]:>13.2f} {s["reference_s"]:>7.2f} '
              f'{s["reference_peak_jerk"]:>10.1f} '
              f'{s["final_joint_error_rad"] * 1e3:>16.2f} '
              f'{s["final_position_error_m"] * 1e3:>12.2f} '
              f'{s["max_line_deviation_m"] * 1e3:>13.2f} '
              f'{np.degrees(s["max_orientation_deviation_rad"]):>16.2f}')


def reexec_in_ros_environment(argv):
    """Run this benchmark again through ``run.sh exec`` when the nodes' messages are missing."""
    if importlib.util.find_spec('control_msgs') is not None:
        return
    if os.environ.get('BENCH_PROFILES_REEXEC'):
        raise SystemExit('control_msgs is not importable even inside run.sh exec')
    os.environ['BENCH_PROFILES_REEXEC'] = '1'
    run_sh = os.path.join(ROOT, 'run.sh')
    print('control_msgs not importable: re-running through ./run.sh exec', flush=True)
    os.chdir(ROOT)
    os.execv(run_sh, [run_sh, 'exec', 'python', '-m', 'bench.bench_profiles'] + list(argv))


def main(argv=None):
    """Run the benchmark; return the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='one run per profile')
    parser.add_argument('--runs', type=int, default=None, help='runs per profile (3)')
    parser.add_argument('--profiles', nargs='+', choices=PROFILES, default=list(PROFILES))
    args = parser.parse_args(argv)
    reexec_in_ros_environment(argv)
    local_dds.apply_default(os.environ)   # the launchers' DDS: loopback only
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
    from mover6_control.kinematics.arm import mover6
    import rclpy

    runs = args.runs or (1 if args.quick else 3)
    t_start = time.monotonic()
    T_goal, goal_text, tried = choose_goal(mover6())
    for entry in tried:
        print(f'goal check: {entry["variant"]}: {entry["message"]}')
    log_dir = tempfile.mkdtemp(prefix='bench_profiles_')
    rclpy.init()
    results, failures = {}, []
    try:
        for profile in args.profiles:
            results[profile] = []
            for k in range(runs):
                r = None
                for attempt in range(ATTEMPTS):
                    run_dir = os.path.join(log_dir, f'{profile}_{k}_{attempt}')
                    os.makedirs(run_dir)
                    try:
                        r = run_once(profile, T_goal, run_dir, timeout=60.0)
                        break
                    except RuntimeError as err:
                        failures.append({'profile': profile, 'run': k, 'error': str(err)})
                        print(f'  {profile} run {k + 1}: attempt {attempt + 1} failed: '
                              f'{str(err).splitlines()[0]}', flush=True)
                if r is None:
                    raise SystemExit(f'{profile}: every attempt failed; logs in {log_dir}')
                results[profile].append(r)
                print(f'  {profile} run {k + 1}/{runs}: arrived in {r["arrive_s"]:.2f} s, line '
                      f'deviation {r["max_line_deviation_m"] * 1e3:.2f} mm', flush=True)
    finally:
        rclpy.try_shutdown()
    summary = {name: summarise(r) for name, r in results.items()}
    print()
    print_table(goal_text, T_goal, summary)
    wall = time.monotonic() - t_start
    if failures:
        print(f'\n{len(failures)} failed attempt(s), each started afresh (see the JSON)')
    print(f'\n{wall:.0f} s wall; node logs in {log_dir}')
    out = {'goal': {'variant': goal_text, 'position_m': T_goal[:3, 3].tolist(),
                    'orientation': 'home orientation kept (R_home @ Rzyx(0, 0, 0))',
                    'n_waypoints': N_WAYPOINTS, 'checks': tried},
           'quick': bool(args.quick), 'runs_per_profile': runs, 'summary': summary,
           'runs': results, 'failed_attempts': failures, 'wall_s': wall}
    write_json('profiles', out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
