"""Partition time for 50, 200 and 1000 agents (bubble packing and randomized fractals).

The thesis circle is scaled with the swarm so the density stays that of chapter 4
(314 m^2 per 50 agents, 20:20:10 types). Prints one line per (method, agents) and
writes bench_partition.json into --out when given.

  scripts/env.sh python benchmarks/bench_partition.py --agents 50,200,1000 --repeats 3
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from swarm_common.robot_types import default_type_counts, load_robot_types
from swarm_common.shapes import load_shape
from swarm_eval.paths import write_json
from swarm_mission.partition import METHODS, partition


def bench(n: int, shape_name: str = 'circle_314', repeats: int = 3,
          methods: tuple[str, ...] = METHODS) -> list[dict]:
    """Partition the thesis shape scaled to ``n`` agents ``repeats`` times (seeds 0..) per method.

    Returns one row per method: median and max seconds (``PartitionResult.seconds``), the
    iterations of each run and the mean irregularities.
    """
    radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
    shape = load_shape(shape_name).scaled(float(np.sqrt(n / 50)))
    rows = []
    for method in methods:
        runs = [partition(shape, default_type_counts(n), radii, method, seed=s)
                for s in range(repeats)]
        seconds = [r.seconds for r in runs]
        rows.append({'agents': n, 'method': method, 'area': shape.area,
                     'seconds_median': float(np.median(seconds)),
                     'seconds_max': float(np.max(seconds)),
                     'iterations': [r.iterations for r in runs],
                     'epsilon_t': float(np.mean([r.epsilon_t for r in runs])),
                     'epsilon_g': float(np.mean([r.epsilon_g for r in runs]))})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--agents', default='50,200,1000')
    parser.add_argument('--shape', default='circle_314')
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--out', default='')
    args = parser.parse_args(argv)
    try:
        sizes = [int(v) for v in args.agents.split(',')]
        if min(sizes) <= 0 or args.repeats <= 0:
            raise ValueError
    except ValueError:
        print('bench_partition: error: --agents must be positive integers like 50,200,1000 '
              'and --repeats positive', file=sys.stderr)
        return 2
    results = []
    for n in sizes:
        for row in bench(n, args.shape, args.repeats):
            results.append(row)
            print(f'{row["method"]:8s} {n:5d} agents ({row["area"]:7.0f} m^2): median '
                  f'{row["seconds_median"]:.2f} s, max {row["seconds_max"]:.2f} s, '
                  f'iterations {row["iterations"]}, eps_t {row["epsilon_t"]:.2f}, '
                  f'eps_g {row["epsilon_g"]:.3f}', flush=True)
    if args.out:
        write_json(args.out, 'bench_partition.json', results)
    return 0



if __name__ == '__main__':
    sys.exit(main())
