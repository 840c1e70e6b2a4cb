#!/usr/bin/env python3
"""Statistical equivalence of two evaluator runs (issue 23; docs/equivalence.md).

  scripts/env.sh python scripts/equivalence_study.py --run 0f6b150 --seeds 20 \\
      --out results/equivalence/before_0f6b150
  scripts/env.sh python scripts/equivalence_study.py \\
      --before results/equivalence/before_0f6b150 --after results/equivalence/after \\
      --out results/equivalence/report.md

The code is ``swarm_eval.equivalence``; ``ros2 run swarm_eval equivalence_study`` is the
same command.
"""

import sys

from swarm_eval.equivalence import main

if __name__ == '__main__':
    sys.exit(main())
