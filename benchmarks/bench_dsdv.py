#!/usr/bin/env python3
"""DSDV convergence after link changes versus network size and packet loss, and routing traffic.

  scripts/env.sh python benchmarks/bench_dsdv.py --agents 50,200 --loss 0,0.1,0.3 \\
      --seeds 5 --out results/bench_dsdv

The code is ``swarm_eval.bench.dsdv``; ``ros2 run swarm_eval bench_dsdv`` is the same command.
"""

import sys

from swarm_eval.bench.dsdv import main

if __name__ == '__main__':
    sys.exit(main())
