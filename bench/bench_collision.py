"""
Collision check cost: per path, and what it adds to a goal's planning.

1. ``CollisionChecker.check_path`` on planned joint paths of 20, 100 and 1000 waypoints (the
   planner's linear moves to two goals, the check's default 0.01 rad sampling): median and p95
   per path, with the dense samples it checked. Goal: under 5 ms at 100 waypoints.
2. Goal-to-demands latency with the check on next to off, at the planner core level
   (``plan_pose_goal`` from home to the same goals, the checker prebuilt as the planner node
   keeps it): the node adds the same DDS hop either way (``bench_planner`` measures the node).

Prints tables, writes bench/results/collision.json. Run alone (``./run.sh bench collision``):
the figures are wall time on whatever else the machine runs.
"""

import argparse
import time

from bench.output import write_json
from mover6_control.collision.checker import CollisionChecker, CollisionSettings
from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.rotations import pose_from_xyzabc
from mover6_control.planning.planner_core import plan_pose_goal, PlannerSettings
import numpy as np

GOALS = (pose_from_xyzabc(0.30, 0.05, 0.36, 0.0, np.pi / 2, 0.0),
         pose_from_xyzabc(0.30, -0.08, 0.32, 0.0, np.pi / 2, 0.0))
SIZES = (20, 100, 1000)


def stats(times):
    """Return median, p95 and max [ms] of times [s]."""
    ms = np.asarray(times) * 1e3
    return {'median_ms': float(np.median(ms)), 'p95_ms': float(np.percentile(ms, 95)),
            'max_ms': float(ms.max())}


def main(argv=None):
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer repeats')
    args = parser.parse_args(argv)
    repeats = 10 if args.quick else 50
    arm = mover6()
    home = np.zeros(6)
    checker = CollisionChecker(arm)
    off = PlannerSettings(collision=CollisionSettings(enabled=False))
    results = {'repeats': repeats, 'check': [], 'latency': []}

    print('check of a planned path (MuJoCo mj_collision per dense sample)')
    print(f'{"waypoints":>10} {"samples":>8} {"median [ms]":>12} {"p95 [ms]":>10} '
          f'{"max [ms]":>10}')
    for n in SIZES:
        settings = PlannerSettings(n_waypoints=n, collision=off.collision)
        paths = [plan_pose_goal(arm, home, T, 'linear', settings).q for T in GOALS]
        times, samples = [], []
        for i in range(repeats):
            t0 = time.perf_counter()
            check = checker.check_path(paths[i % 2])
            times.append(time.perf_counter() - t0)
            samples.append(check.n_samples)
            assert check.free
        row = dict(waypoints=n, samples=int(np.median(samples)), **stats(times))
        results['check'].append(row)
        print(f'{n:>10} {row["samples"]:>8} {row["median_ms"]:>12.2f} {row["p95_ms"]:>10.2f} '
              f'{row["max_ms"]:>10.2f}')

    print('\ngoal to demands (planner core: plan_pose_goal), collision check on vs off')
    print(f'{"waypoints":>10} {"off median":>11} {"off p95":>9} {"on median":>10} '
          f'{"on p95":>8}  [ms]')
    for n in SIZES:
        row = {'waypoints': n}
        for label, collision in (('off', off.collision), ('on', checker.settings)):
            settings = PlannerSettings(n_waypoints=n, collision=collision)
            use = checker if collision.enabled else None
            times = []
            for i in range(repeats):
                t0 = time.perf_counter()
                plan_pose_goal(arm, home, GOALS[i % 2], 'linear', settings, use)
                times.append(time.perf_counter() - t0)
            row[label] = stats(times)
        results['latency'].append(row)
        print(f'{n:>10} {row["off"]["median_ms"]:>11.2f} {row["off"]["p95_ms"]:>9.2f} '
              f'{row["on"]["median_ms"]:>10.2f} {row["on"]["p95_ms"]:>8.2f}')

    p95_100 = next(r['p95_ms'] for r in results['check'] if r['waypoints'] == 100)
    results['goal_p95_100_waypoints_ms'] = 5.0
    results['goal_met'] = p95_100 < 5.0
    print(f'\ngoal: check of a 100-waypoint path under 5 ms (p95): '
          f'{"met" if results["goal_met"] else "MISSED"} ({p95_100:.2f} ms)')
    write_json('collision', results)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
