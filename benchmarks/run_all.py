#!/usr/bin/env python3
"""The benchmark suite in one command: writes docs/benchmarks.md and docs/benchmarks.json.

  scripts/env.sh python benchmarks/run_all.py                 # the suite, into docs/
  scripts/env.sh python benchmarks/run_all.py --sizes 10 --repeats 1 --quick --out /tmp/q

The code is ``swarm_eval.bench.suite``; ``ros2 run swarm_eval benchmarks`` is the same command.
"""

import sys

from swarm_eval.bench.suite import main

if __name__ == '__main__':
    sys.exit(main())
