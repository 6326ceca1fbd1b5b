"""
Run every benchmark in turn: ``./run.sh bench [--quick] [name ...]``.

Each benchmark is a module ``bench.bench_<name>`` that prints its table and writes
``bench/results/<name>.json``; this runner starts each in its own process (so one cannot disturb
the next), then writes ``bench/results/summary.json`` with every result.
"""

import glob
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, 'results')


def available():
    """Return the names of the benchmark modules, in a fixed order."""
    return sorted(os.path.basename(p)[len('bench_'):-3]
                  for p in glob.glob(os.path.join(HERE, 'bench_*.py')))


def main(argv):
    """
    Run the benchmarks named in ``argv`` (all by default); return the exit code.

    Options go to every benchmark; a word right after an option that is no benchmark's name is
    that option's value (``churn --repeat 3``).
    """
    names, flags = [], []
    for i, arg in enumerate(argv):
        if arg.startswith('-') or (i > 0 and argv[i - 1].startswith('-')
                                   and arg not in available()):
            flags.append(arg)
        else:
            names.append(arg)
    names = names or available()
    unknown = sorted(set(names) - set(available()))
    if unknown:
        print(f'unknown benchmarks {unknown}; available: {available()}', file=sys.stderr)
        return 2
    os.makedirs(RESULTS, exist_ok=True)
    summary_path = os.path.join(RESULTS, 'summary.json')
    summary, failed = {}, []
    if os.path.exists(summary_path):      # a run of some benchmarks keeps the others' figures
        with open(summary_path) as f:
            summary = json.load(f)
    for name in names:
        print(f'\n=== bench_{name} {" ".join(flags)}', flush=True)
        t0 = time.monotonic()
        rc = subprocess.call([sys.executable, '-m', f'bench.bench_{name}'] + flags,
                             cwd=os.path.dirname(HERE))
        path = os.path.join(RESULTS, f'{name}.json')
        if rc != 0:
            failed.append(name)
        if os.path.exists(path):
            with open(path) as f:
                summary[name] = json.load(f)
        print(f'=== bench_{name}: exit {rc}, {time.monotonic() - t0:.1f} s', flush=True)
    with open(summary_path, 'w') as f:
        json.dump(summary, f, indent=2)
    print(f'\nresults: {RESULTS}/ (summary.json)' + (f'; FAILED: {failed}' if failed else ''))
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
