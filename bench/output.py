"""Where the benchmarks write their figures: ``bench/results/<name>.json``."""

import json
import os

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'results')


def write_json(name, data):
    """Write ``data`` to ``RESULTS/<name>.json``, say where, and return the path."""
    os.makedirs(RESULTS, exist_ok=True)
    path = os.path.join(RESULTS, f'{name}.json')
    with open(path, 'w') as f:
        json.dump(data, f, indent=2)
    print(f'\nwritten {path}')
    return path
