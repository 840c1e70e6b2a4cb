#!/usr/bin/env python3
"""Partition time for 50, 200 and 1000 agents (bubble packing and randomized fractals).

  scripts/env.sh python benchmarks/bench_partition.py --agents 50,200,1000 --repeats 3

The code is ``swarm_eval.bench.partition`` (also the suite's partition section).
"""

import sys

from swarm_eval.bench.partition import main

if __name__ == '__main__':
    sys.exit(main())
