"""
Benchmark of the motion library: build and sample speed, and the Mover6 report's linear move.

Run: ``python -m bench.bench_motion [--quick]``. Prints tables and writes
``bench/results/motion.json``.

1. Speed: build a trajectory through 100 joint waypoints and sample it at 1 kHz, for each kind
   (continuous TOPP timing, cubic, quintic, B-spline, multi-point trapezoid, the Mover6 report's
   stop-at-each trapezoids, ruckig point-to-point).
2. The Mover6 report's linear example: X=0.445 Y=0 Z=0.4425 A=B=C=0 from home (q = 0), 20
   waypoints, the Mover6 hardware speed limits (arm.py) and a_max = 1 rad/s^2 (the controller's
   default). A B C are composed relative to the home orientation as the Mover6 report's MATLAB does
   (R_goal = R_home Rzyx(A, B, C)): the tool keeps its orientation and moves 0.1 m along +x.
   Compared: the Mover6 report's scheme (a trapezoid per waypoint, t_blend = t_max / 4, stop at
   each; both the report's fixed t_max = 1 s and the shortest t_max the limits allow) against
   continuous execution, with the largest Cartesian deviation of each from the straight line (FK
   every 1 ms) and the continuous duration against a lower bound on any trajectory. Plots (PNG,
   next to the JSON): the time laws, the continuous joint trajectories against the joint limits,
   the desired against the realised tool path.
3. Plan time: the continuous timing (``time_optimal.time_parameterize``, as the controller's
   ``continuous`` profile calls it) through 20, 100, 1000 and 10,000 random in-limit waypoints,
   the median of several runs, with the durations (a faster timing must not change them), beside
   toppra in the same run on identical inputs (``peer_toppra``: toppra on our path and grid, and
   toppra on a spline through the same waypoints), with the largest sampled velocity and
   acceleration over the limits of each and the ratios of the run times.
"""

import argparse
import os
import time

from bench import peer_toppra
from bench.output import RESULTS, write_json
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.rotations import goal_relative_to_start
from mover6_control.motion import metrics, paths
from mover6_control.motion.timing import (jerk_limited, spline_trajectories, time_laws,
                                          time_optimal, trajectories)
from mover6_control.tools import plots
import numpy as np

A_MAX = 1.0     # [rad/s^2] the controller's default acceleration limit
J_MAX = 5.0     # [rad/s^3] the controller's default jerk limit


def _solve_path(arm, poses, q_start):
    """Joint waypoints for the poses: path_ik when it exists, else closed-form IK per pose."""
    try:
        from mover6_control.kinematics.path_ik import solve_path
    except ImportError:
        solve_path = None
    if solve_path is not None:
        return np.asarray(solve_path(arm, poses, q_start).q), 'path_ik.solve_path'
    from mover6_control.kinematics.ik_closed_form import ik_closed_form
    Q, q = [], np.asarray(q_start, dtype=float)
    for T in poses:
        sols = ik_closed_form(arm, T, q_ref=q)
        if sols.shape[0] == 0:
            raise RuntimeError('no IK solution on the report path')
        q = sols[0]
        Q.append(q)
    return np.array(Q), 'ik.ik_closed_form (nearest to previous)'


def _timed(fn, repeats):
    best = np.inf
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _plan_times(fn, repeats):
    """Return the result of ``fn`` and the median and shortest of its run times [s]."""
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times)), min(times)


def _waypoints(arm, m, seed=0):
    """Return a smooth random joint path (m, 6) well inside the hardware limits."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(scale=0.05, size=(m, arm.n_joints))
    Q = np.cumsum(steps, axis=0)
    Q -= Q.mean(axis=0)
    span = 0.6 * np.minimum(-arm.lower, arm.upper)
    return np.clip(Q, -span, span)


def bench_speed(arm, quick):
    """Build and sample each kind of trajectory through 100 waypoints at 1 kHz."""
    Q = _waypoints(arm, 100)
    v = arm.velocity_limits
    builders = {
        'continuous (TOPP)': lambda: time_optimal.time_parameterize(Q, v, A_MAX),
        'continuous, jerk-limited': lambda: time_optimal.time_parameterize(Q, v, A_MAX,
                                                                           j_max=J_MAX),
        'cubic spline': lambda: spline_trajectories.cubic_trajectory(Q, v_max=v, a_max=A_MAX),
        'quintic spline': lambda: spline_trajectories.quintic_trajectory(Q, v_max=v, a_max=A_MAX),
        'B-spline': lambda: spline_trajectories.bspline_trajectory(Q, v_max=v, a_max=A_MAX),
        'multi-point trapezoid': lambda: spline_trajectories.multipoint_trapezoidal(Q, v, A_MAX),
        'report stop-at-each': lambda: trajectories.stop_at_each(
            Q, time_laws.trapezoidal, v, A_MAX),
        'ruckig point-to-point': lambda: jerk_limited.ruckig_trajectory(
            Q[0], Q[-1], v, A_MAX, J_MAX),
    }
    repeats = 1 if quick else 3
    rows = []
    for name, build in builders.items():
        traj, t_build = _timed(build, repeats)
        t = metrics.sample_times(traj.duration, 1e-3)
        if quick:
            t = t[:20000]
        _, t_batch = _timed(lambda: traj.sample(t), repeats)
        ticks = t[:: max(1, t.size // 500)]
        t0 = time.perf_counter()
        for ti in ticks:
            traj.sample(float(ti))
        t_tick = (time.perf_counter() - t0) / ticks.size
        rows.append({'kind': name, 'duration_s': traj.duration, 'build_ms': 1e3 * t_build,
                     'sample_batch_us': 1e6 * t_batch / t.size, 'sample_tick_us': 1e6 * t_tick,
                     'samples': int(t.size)})
    bound = time_optimal.time_optimal_bound(Q, v, A_MAX)
    return rows, bound


def bench_plan_time(arm, quick):
    """
    Plan time of the continuous timing beside toppra's, on identical inputs, per waypoint count.

    For each set (random waypoints, seeded by their count): ours (``time_parameterize``, the
    median of several runs), toppra on our path and grid (``peer_toppra.same_path``) and toppra
    on a spline through the same waypoints (``peer_toppra.spline``), with every duration, the
    largest sampled joint velocity and acceleration over their limits (1 kHz) and the ratios of
    the run times (toppra / ours: above 1, ours is faster).
    """
    v = arm.velocity_limits
    a = np.full(arm.n_joints, A_MAX)
    sets = ((20, 15), (100, 15), (1000, 3))
    if not quick:
        sets += ((10000, 1),)
    rows = []
    for m, repeats in sets:
        repeats = 1 if quick else repeats
        peer_repeats = max(1, min(repeats, 5))
        Q = _waypoints(arm, m, seed=m)
        traj, t_plan, t_min = peer_toppra.timed(
            lambda: time_optimal.time_parameterize(Q, v, A_MAX), repeats)
        row = {'waypoints': m, 'plan_ms': 1e3 * t_plan, 'plan_ms_min': 1e3 * t_min,
               'duration_s': traj.duration, 'repeats': repeats,
               'bound_s': time_optimal.time_optimal_bound(Q, v, A_MAX)}
        row['v_ratio'], row['a_ratio'] = peer_toppra.limit_ratios(
            lambda t: traj.sample(t)[1:], traj.duration, v, a)
        for name, build in (('toppra_same_path', peer_toppra.same_path(traj, v, a)),
                            ('toppra_spline', peer_toppra.spline(Q, v, a))):
            peer, t_peer, _ = peer_toppra.timed(build, peer_repeats)
            v_ratio, a_ratio = peer_toppra.limit_ratios(peer_toppra.toppra_sampler(peer),
                                                        peer.duration, v, a)
            row[name] = {'plan_ms': 1e3 * t_peer, 'duration_s': float(peer.duration),
                         'v_ratio': v_ratio, 'a_ratio': a_ratio, 'repeats': peer_repeats,
                         'speed_ratio': t_peer / t_plan}
        rows.append(row)
    return rows


def bench_linear_goal(quick):
    """
    Time a 1000-waypoint linear goal as the planner plans it, beside toppra.

    The planner's own plan (``plan_pose_goal``, 1000 waypoints, from home to the planner
    bench's first goal): a smooth path, where toppra's grid is coarse. Ours (median of runs)
    against toppra on a spline through the same waypoints with its default grid (the issue's
    "toppra's timing alone") and on our path and grid.
    """
    from mover6_control.kinematics.rotations import pose_from_xyzabc
    from mover6_control.planning.planner_core import PlannerSettings, plan_pose_goal

    arm = mover6()
    goal = pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0)
    Q = np.asarray(plan_pose_goal(arm, np.zeros(6), goal, 'linear',
                                  PlannerSettings(n_waypoints=1000)).q)
    v, a = arm.velocity_limits, np.full(arm.n_joints, A_MAX)
    repeats = 1 if quick else 5
    traj, t_ours, _ = peer_toppra.timed(lambda: time_optimal.time_parameterize(Q, v, A_MAX),
                                        repeats)
    row = {'waypoints': int(Q.shape[0]), 'plan_ms': 1e3 * t_ours, 'duration_s': traj.duration}
    for name, build in (('toppra_spline', peer_toppra.spline(Q, v, a)),
                        ('toppra_same_path', peer_toppra.same_path(traj, v, a))):
        peer, t_peer, _ = peer_toppra.timed(build, repeats)
        row[name] = {'plan_ms': 1e3 * t_peer, 'duration_s': float(peer.duration),
                     'speed_ratio': t_peer / t_ours}
    return row


def print_plan_time(plan):
    """Print ``bench_plan_time``'s rows: ours, then each toppra call, side by side."""
    print('\nPlan time of the continuous timing beside toppra on the same waypoints (random,'
          ' hardware speed limits, a_max = 1 rad/s^2); v, a: largest sampled |qd| / v_max,'
          ' |qdd| / a_max; x: toppra time / ours')
    print(f'{"waypoints":>9s} | {"ours ms":>8s} {"dur s":>9s} {"v":>5s} {"a":>5s} |'
          f' {"same path ms":>12s} {"dur s":>9s} {"v":>5s} {"a":>5s} {"x":>6s} |'
          f' {"spline ms":>9s} {"dur s":>9s} {"v":>5s} {"a":>5s} {"x":>6s} | {"bound s":>8s}')
    for r in plan:
        cells = [f'{r["waypoints"]:9d} | {r["plan_ms"]:8.1f} {r["duration_s"]:9.3f}'
                 f' {r["v_ratio"]:5.3f} {r["a_ratio"]:5.3f}']
        for name in ('toppra_same_path', 'toppra_spline'):
            p = r[name]
            width = 12 if name == 'toppra_same_path' else 9
            cells.append(f' {p["plan_ms"]:{width}.1f} {p["duration_s"]:9.3f} {p["v_ratio"]:5.3f}'
                         f' {p["a_ratio"]:5.3f} {p["speed_ratio"]:6.1f}')
        print(' |'.join(cells) + f' | {r["bound_s"]:8.3f}')


def bench_report_linear(arm):
    """Time the Mover6 report's linear example: its stop-at-each scheme against continuous."""
    q_home = np.zeros(arm.n_joints)
    T_home = fk(arm, q_home)
    T_goal = goal_relative_to_start(T_home, 0.445, 0.0, 0.4425, 0.0, 0.0, 0.0)
    poses = paths.linear_curve(T_home, T_goal, n=20).poses
    Q, ik_used = _solve_path(arm, poses, q_home)
    line = paths.positions_of(poses)[[0, -1]]
    v = arm.velocity_limits

    def fk_fn(Qs):
        return fk_batch(arm, Qs)

    schemes = {}
    report_fixed = trajectories.PiecewiseTrajectory(
        [trajectories.TimeLawTrajectory(Q[k], Q[k + 1], 1.0, time_laws.trapezoidal(1.0))
         for k in range(len(Q) - 1)])
    schemes['report scheme, t_max = 1 s per waypoint'] = report_fixed
    schemes['report scheme, shortest t_max'] = trajectories.stop_at_each(
        Q, time_laws.trapezoidal, v, A_MAX)
    cont, t_build = _timed(lambda: time_optimal.time_parameterize(Q, v, A_MAX), 3)
    schemes['continuous (TOPP on blended path)'] = cont
    schemes['continuous, jerk-limited (j_max 5)'] = time_optimal.time_parameterize(
        Q, v, A_MAX, j_max=J_MAX)
    bound = time_optimal.time_optimal_bound(Q, v, A_MAX)
    fine = time_optimal.time_parameterize(Q, v, A_MAX, n_grid=20000)
    t = metrics.sample_times(cont.duration, 1e-3)
    q, qd, qdd = cont.sample(t)
    figures = [
        plots.plot_time_law([time_laws.cubic(), time_laws.quintic(), time_laws.septic(),
                             time_laws.trapezoidal(), time_laws.sharp_trapezoid(),
                             time_laws.via_point_polynomial(
                                 time_laws.via_fraction(83.14, 90.0, 173.37))],
                            os.path.join(RESULTS, 'motion_time_laws.png')),
        plots.plot_joint_trajectories(t, q, arm.lower, arm.upper,
                                      os.path.join(RESULTS, 'motion_report_joints.png'),
                                      QD=qd, QDD=qdd),
        plots.plot_path_3d(paths.positions_of(poses), fk_batch(arm, q)[:, :3, 3],
                           os.path.join(RESULTS, 'motion_report_path3d.png'),
                           waypoints=fk_batch(arm, Q)[:, :3, 3]),
    ]
    rows = []
    for name, traj in schemes.items():
        mt = metrics.trajectory_metrics(traj, fk_fn, line, dt=1e-3)
        rows.append({
            'scheme': name, 'duration_s': mt.duration,
            'max_deviation_mm': 1e3 * mt.max_deviation,
            'peak_v_over_limit': float(np.max(mt.peak_velocity / v)),
            'peak_a_rad_s2': float(np.max(mt.peak_acceleration)),
            'path_length_m': mt.path_length})
    base = rows[1]['duration_s']
    sweep = []
    for a_max in (0.5, 1.0, 2.0, 5.0):
        report_t = trajectories.stop_at_each(Q, time_laws.trapezoidal, v, a_max).duration
        cont_t = time_optimal.time_parameterize(Q, v, a_max).duration
        sweep.append({'a_max': a_max, 'report_shortest_s': report_t, 'continuous_s': cont_t,
                      'speedup': report_t / cont_t,
                      'bound_s': time_optimal.time_optimal_bound(Q, v, a_max)})
    return {
        'figures': figures, 'a_max_sweep': sweep,
        'ik': ik_used, 'a_max': A_MAX, 'velocity_limits': v.tolist(), 'rows': rows,
        'speedup_vs_report_shortest': base / cont.duration,
        'speedup_vs_report_fixed_1s': rows[0]['duration_s'] / cont.duration,
        'lower_bound_s': bound, 'continuous_over_bound': cont.duration / bound,
        'topp_fine_grid_s': fine.duration, 'continuous_build_ms': 1e3 * t_build,
    }


def main(argv=None):
    """Run the benchmark, print tables, write bench/results/motion.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--quick', action='store_true', help='fewer repeats and samples')
    args = parser.parse_args(argv)
    arm = mover6('hardware')
    speed, bound100 = bench_speed(arm, args.quick)
    print('100 joint waypoints, hardware speed limits, a_max = 1 rad/s^2, sampled at 1 kHz')
    print(f'{"kind":26s} {"duration s":>10s} {"build ms":>9s} {"batch us/sample":>16s}'
          f' {"tick us":>8s}')
    for r in speed:
        print(f'{r["kind"]:26s} {r["duration_s"]:10.2f} {r["build_ms"]:9.2f}'
              f' {r["sample_batch_us"]:16.3f} {r["sample_tick_us"]:8.1f}')
    print(f'lower bound on any trajectory through these waypoints: {bound100:.2f} s')
    plan = bench_plan_time(arm, args.quick)
    print_plan_time(plan)
    linear = bench_linear_goal(args.quick)
    print(f'\nThe planner\'s 1000-waypoint linear goal ({linear["waypoints"]} rows): ours'
          f' {linear["plan_ms"]:.1f} ms ({linear["duration_s"]:.3f} s); toppra on a spline,'
          f' its grid: {linear["toppra_spline"]["plan_ms"]:.1f} ms'
          f' ({linear["toppra_spline"]["duration_s"]:.3f} s); toppra on our path and grid:'
          f' {linear["toppra_same_path"]["plan_ms"]:.1f} ms'
          f' ({linear["toppra_same_path"]["duration_s"]:.3f} s)')
    report = bench_report_linear(arm)
    print('\nThe Mover6 report linear example (0.1 m along +x, home orientation kept),'
          f' IK: {report["ik"]}')
    print(f'{"scheme":38s} {"duration s":>10s} {"max dev mm":>10s} {"peak v/limit":>12s}'
          f' {"peak a":>7s}')
    for r in report['rows']:
        print(f'{r["scheme"]:38s} {r["duration_s"]:10.3f} {r["max_deviation_mm"]:10.4f}'
              f' {r["peak_v_over_limit"]:12.3f} {r["peak_a_rad_s2"]:7.3f}')
    print(f'continuous is {report["speedup_vs_report_shortest"]:.2f}x faster than the report'
          ' scheme'
          f' (shortest t_max), {report["speedup_vs_report_fixed_1s"]:.2f}x than its fixed 1 s')
    print('speed-up against the report scheme at its fastest, by acceleration limit:')
    for r in report['a_max_sweep']:
        print(f'  a_max {r["a_max"]:4.1f} rad/s^2: report {r["report_shortest_s"]:6.3f} s,'
              f' continuous {r["continuous_s"]:6.3f} s (bound {r["bound_s"]:6.3f} s),'
              f' {r["speedup"]:.2f}x')
    print(f'lower bound {report["lower_bound_s"]:.3f} s; continuous / bound ='
          f' {report["continuous_over_bound"]:.3f}; TOPP on a 20000-point grid'
          f' {report["topp_fine_grid_s"]:.3f} s')
    out = {'quick': args.quick, 'speed_100_waypoints': speed, 'plan_time': plan,
           'linear_goal_1000': linear,
           'lower_bound_100_waypoints_s': bound100, 'report_linear': report}
    write_json('motion', out)
    print(f'figures: {", ".join(report["figures"])}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
