"""
Benchmark of inverse kinematics: closed form (batched and per pose) and numeric, with a baseline.

Run: ``python -m bench.bench_ik [--quick]``. Prints a table and writes
``bench/results/ik.json``. Runs on one core: the module re-executes itself with
``OPENBLAS_NUM_THREADS=1`` (and the OpenMP / MKL equivalents) when they are not set.

Poses: FK of configurations drawn uniformly inside the joint limits (10,000; 2,000 with
``--quick``), for the Mover6 (seed limits, [-1.571, 1.571] rad) and the miniBOT (the miniBOT
report).

Times are wall clock and CPU time of this process (``time.process_time``): on a shared machine
the CPU figure is the fairer one; the load average is printed. Each timing is the least of
several runs (batch: 5; per pose: 2), the usual guard against interference.

1. Closed form, batched (``ik.ik_closed_form_batch``): poses per second (best of 5; wall and
   CPU time), share of poses solved, share whose generating configuration is among the
   solutions, largest FK round-trip error over every returned solution, mean number of
   solutions.
2. Closed form, one pose per call (``ik.ik_closed_form``): median and 99th-percentile latency.
3. Numeric (``ik_numeric.ik_numeric`` from q0 = 0, tolerance 1e-6 m and 1e-6 rad): success rate
   and median time, on the same poses (all 10,000; the first 100 with ``--quick``).
4. Baseline any user could write: ``scipy.optimize.least_squares`` on the same weighted cost
   (position [m] and rotation vector [rad], same weights), bounded by the joint limits, from
   q0 = 0 and then random starts (4 starts at most), finite-difference Jacobian; on the first
   300 poses (20 with ``--quick``), with the ratio of median times against ``ik_numeric`` on
   those same poses.

5. Peer from the package registry: ikpy (``Chain.from_urdf_file`` on the same URDF,
   ``inverse_kinematics_frame`` with ``orientation_mode='all'``, from q0 = 0) on the same poses as
   the baseline (Mover6 only: ikpy reads URDF, the miniBOT is a DH table), with success at the
   same tolerance and at 1e-3 and the ratio of its median time to ``ik_numeric``'s.

Anchors (published figures of the peers): TRAC-IK 99.8-100 % at 0.2-0.4 ms; KDL 26-75 %.
"""

import argparse
import os
import subprocess
import sys
import time

from bench.output import write_json
from mover6_control.kinematics.arm import minibot, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.ik_closed_form import (ik_closed_form, ik_closed_form_batch,
                                                      pose_errors_batch)
from mover6_control.kinematics.ik_numeric import DEFAULT_WEIGHTS, ik_numeric
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

THREAD_VARS = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')
TOL = 1e-6   # [m] and [rad] success tolerance of both numeric solvers
REPEATS = 2  # per-pose timings: the least of this many runs (the machine may be shared)


def _poses(arm, m, seed=0):
    """Return configurations (m, 6) inside the limits and their poses (m, 4, 4)."""
    Q = np.random.default_rng(seed).uniform(arm.lower, arm.upper, (m, arm.n_joints))
    return Q, fk_batch(arm, Q)


def closed_form_batch(arm, Q, T):
    """Throughput and accuracy of the batched closed form."""
    ik_closed_form_batch(arm, T[:256])      # warm-up (first-call allocations)
    (S, ok), wall, cpu = _timed(lambda: ik_closed_form_batch(arm, T), 5)
    m = len(T)
    dp, dr = pose_errors_batch(np.repeat(T, 8, axis=0), fk_batch(arm, S.reshape(-1, 6)))
    good = ok.reshape(-1)
    dist = np.where(ok, np.abs(S - Q[:, None]).max(axis=2), np.inf).min(axis=1)
    return {'poses': m, 'poses_per_s_wall': m / wall, 'poses_per_s_cpu': m / cpu,
            'solved': float(ok.any(axis=1).mean()), 'generator_found': float(np.mean(dist < 1e-8)),
            'max_position_error_m': float(dp[good].max()),
            'max_orientation_error_rad': float(dr[good].max()),
            'mean_solutions': float(ok.sum(axis=1).mean())}


def _timed(fn, repeats):
    """Return (result of the first call, least wall time, least CPU time) over ``repeats``."""
    wall, cpu, out = np.inf, np.inf, None
    for i in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
        out = res if i == 0 else out
    return out, wall, cpu


def closed_form_single(arm, T, repeats=REPEATS):
    """Per-pose latency of ``ik_closed_form`` (wall and CPU time, least of ``repeats``)."""
    wall, cpu = [], []
    for pose in T:
        _, w, c = _timed(lambda: ik_closed_form(arm, pose), repeats)
        wall.append(w)
        cpu.append(c)
    wall, cpu = np.array(wall) * 1e6, np.array(cpu) * 1e6
    return {'poses': len(T), 'median_us': float(np.median(wall)),
            'p99_us': float(np.percentile(wall, 99)), 'median_us_cpu': float(np.median(cpu))}


def numeric(arm, T, repeats=REPEATS):
    """Success, wall and CPU times [ms] and iterations of ``ik_numeric`` from q0 = 0."""
    wall, cpu, ok, iters = [], [], [], []
    for k, pose in enumerate(T):
        res, w, c = _timed(lambda: ik_numeric(arm, pose, np.zeros(arm.n_joints),
                                              position_tol=TOL, orientation_tol=TOL, rng=k),
                           repeats)
        wall.append(w)
        cpu.append(c)
        ok.append(res.success)
        iters.append(res.iterations)
    return np.array(wall) * 1e3, np.array(cpu) * 1e3, np.array(ok), np.array(iters)


def _residual(arm, T, sqrt_w):
    def fun(q):
        Tq = fk(arm, q)
        rot = Rotation.from_matrix(T[:3, :3] @ Tq[:3, :3].T).as_rotvec()
        return sqrt_w * np.concatenate([T[:3, 3] - Tq[:3, 3], rot])
    return fun


def scipy_baseline(arm, T, starts=4):
    """Success rate and times [ms] of least_squares on the same cost."""
    sqrt_w = np.sqrt(np.asarray(DEFAULT_WEIGHTS))
    lo, hi = arm.lower, arm.upper
    times, ok = [], []
    for k, pose in enumerate(T):
        rng = np.random.default_rng(k)
        fun = _residual(arm, pose, sqrt_w)
        t0 = time.perf_counter()
        success = False
        q0 = np.clip(np.zeros(arm.n_joints), lo, hi)
        for _ in range(starts):
            sol = least_squares(fun, q0, bounds=(lo, hi), xtol=1e-12, ftol=1e-12, gtol=1e-12)
            Tq = fk(arm, sol.x)
            pos = np.linalg.norm(Tq[:3, 3] - pose[:3, 3])
            rot = np.linalg.norm(Rotation.from_matrix(pose[:3, :3] @ Tq[:3, :3].T).as_rotvec())
            if pos < TOL and rot < TOL:
                success = True
                break
            q0 = rng.uniform(lo, hi)
        times.append(time.perf_counter() - t0)
        ok.append(success)
    return np.array(times) * 1e3, np.array(ok)


def ikpy_peer(arm, T):
    """Success (at TOL and at 1e-3) and times [ms] of ikpy on the poses ``T`` (Mover6 URDF)."""
    import warnings

    from ikpy.chain import Chain
    from mover6_control.resources import CONFIG_DIR

    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        # ikpy follows the URDF to its leaf (past link6: the gripper's joint); the arm's chain
        # is its origin link and the six joints up to link6, the model's tip.
        full = Chain.from_urdf_file(os.path.join(CONFIG_DIR, 'mover6.urdf'),
                                    base_elements=['base_link'])
        links = full.links[:1 + arm.n_joints]
        if tuple(link.name for link in links[1:]) != arm.joint_names:
            raise RuntimeError(f'ikpy chain {[link.name for link in full.links]} does not '
                               f'start with the joints {arm.joint_names}')
        chain = Chain(links, active_links_mask=[False] + [True] * arm.n_joints, name=arm.name)
    q0 = np.zeros(len(chain.links))
    times, errors = [], []
    for pose in T:
        t0 = time.perf_counter()
        full = chain.inverse_kinematics_frame(pose, initial_position=q0, orientation_mode='all')
        times.append(time.perf_counter() - t0)
        Tq = fk(arm, full[1:1 + arm.n_joints])
        errors.append(pose_errors_batch(pose, Tq))
    errors = np.array(errors, dtype=float)
    worst = errors.max(axis=1)
    return np.array(times) * 1e3, worst < TOL, worst < 1e-3


def run(quick):
    """Run every part for both arms; return the results dictionary."""
    n_cf, n_single, n_num, n_base = (2000, 100, 100, 20) if quick else (10000, 2000, 10000, 300)
    out = {'quick': quick, 'load_average': os.getloadavg()[0], 'arms': {}}
    for arm in (mover6(), minibot()):
        Q, T = _poses(arm, n_cf)
        r = {'closed_form_batch': closed_form_batch(arm, Q, T),
             'closed_form_single': closed_form_single(arm, T[:n_single])}
        t_num, c_num, ok_num, iters = numeric(arm, T[:n_num])
        r['numeric'] = {'poses': n_num, 'success': float(ok_num.mean()),
                        'median_ms': float(np.median(t_num)),
                        'median_ms_cpu': float(np.median(c_num)),
                        'p90_ms': float(np.percentile(t_num, 90)),
                        'median_iterations': float(np.median(iters))}
        t_base, ok_base = scipy_baseline(arm, T[:n_base])
        ours = np.median(t_num[:n_base])
        r['scipy_baseline'] = {'poses': n_base, 'success': float(ok_base.mean()),
                               'median_ms': float(np.median(t_base)),
                               'ik_numeric_median_ms_same_poses': float(ours),
                               'ik_numeric_success_same_poses': float(ok_num[:n_base].mean()),
                               'speedup': float(np.median(t_base) / ours)}
        if arm.name == 'mover6':
            t_ikpy, ok_ikpy, loose_ikpy = ikpy_peer(arm, T[:n_base])
            r['ikpy'] = {'poses': n_base, 'success': float(ok_ikpy.mean()),
                         'success_1e-3': float(loose_ikpy.mean()),
                         'median_ms': float(np.median(t_ikpy)),
                         'ik_numeric_median_ms_same_poses': float(ours),
                         'speedup': float(np.median(t_ikpy) / ours)}
        out['arms'][arm.name] = r
    return out


def print_table(out):
    """Print the results as a table."""
    print(f'IK benchmark (quick={out["quick"]}, one core, load average '
          f'{out["load_average"]:.2f})')
    head = f'{"":34s}' + ''.join(f'{name:>18s}' for name in out['arms'])
    print(head)
    rows = [
        ('closed form batch [poses/s wall]', 'closed_form_batch', 'poses_per_s_wall', '.0f'),
        ('closed form batch [poses/s cpu]', 'closed_form_batch', 'poses_per_s_cpu', '.0f'),
        ('  solved [share]', 'closed_form_batch', 'solved', '.4f'),
        ('  generator among solutions', 'closed_form_batch', 'generator_found', '.4f'),
        ('  max round trip [m]', 'closed_form_batch', 'max_position_error_m', '.1e'),
        ('  max round trip [rad]', 'closed_form_batch', 'max_orientation_error_rad', '.1e'),
        ('  mean solutions in limits', 'closed_form_batch', 'mean_solutions', '.2f'),
        ('closed form one pose [us, median]', 'closed_form_single', 'median_us', '.0f'),
        ('closed form one pose [us, p99]', 'closed_form_single', 'p99_us', '.0f'),
        ('closed form one pose [us, cpu med]', 'closed_form_single', 'median_us_cpu', '.0f'),
        ('ik_numeric success', 'numeric', 'success', '.4f'),
        ('ik_numeric median [ms]', 'numeric', 'median_ms', '.2f'),
        ('ik_numeric median [ms, cpu]', 'numeric', 'median_ms_cpu', '.2f'),
        ('ik_numeric p90 [ms]', 'numeric', 'p90_ms', '.2f'),
        ('scipy least_squares success', 'scipy_baseline', 'success', '.4f'),
        ('scipy least_squares median [ms]', 'scipy_baseline', 'median_ms', '.2f'),
        ('ik_numeric median, same [ms]', 'scipy_baseline', 'ik_numeric_median_ms_same_poses',
         '.2f'),
        ('speed-up over scipy [x]', 'scipy_baseline', 'speedup', '.1f'),
    ]
    rows += [
        ('ikpy success (peer)', 'ikpy', 'success', '.4f'),
        ('ikpy success at 1e-3', 'ikpy', 'success_1e-3', '.4f'),
        ('ikpy median [ms]', 'ikpy', 'median_ms', '.2f'),
        ('ikpy / ik_numeric [x]', 'ikpy', 'speedup', '.1f'),
    ]
    for label, part, key, fmt in rows:
        print(f'{label:34s}' + ''.join(
            f'{format(r[part][key], fmt) if part in r else "-":>18s}'
            for r in out['arms'].values()))
    for name, r in out['arms'].items():
        print(f'{name}: {r["closed_form_batch"]["poses"]} poses closed form, '
              f'{r["numeric"]["poses"]} numeric, {r["scipy_baseline"]["poses"]} scipy')


def main(argv=None):
    """Parse arguments, run on one core, print the table and write the JSON."""
    argv = sys.argv[1:] if argv is None else argv
    if any(os.environ.get(var) != '1' for var in THREAD_VARS):
        env = dict(os.environ, **dict.fromkeys(THREAD_VARS, '1'))
        return subprocess.call([sys.executable, '-m', 'bench.bench_ik'] + list(argv), env=env)
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--quick', action='store_true', help='fewer poses (< 20 s)')
    args = parser.parse_args(argv)
    out = run(args.quick)
    print_table(out)
    write_json('ik', out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
