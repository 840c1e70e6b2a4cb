#!/usr/bin/env python3
"""Headless Monte Carlo evaluation of a formation method (thesis 4.3): --help lists the options.

  scripts/env.sh python scripts/evaluate.py --method bubble --shape circle_314 \\
      --agents 50 --beacons 8 --trials 4 --workers 2 --out results/eval_bubble

The code is ``swarm_eval.evaluate``; ``ros2 run swarm_eval evaluate`` is the same command.
"""

import sys

from swarm_eval.evaluate import main

if __name__ == '__main__':
    sys.exit(main())
