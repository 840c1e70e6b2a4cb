#!/usr/bin/env python3
"""Compare the three formation methods (thesis Table 4.4) and dynamic formations (4.3.4).

  scripts/env.sh python scripts/method_study.py --agents 50 --trials 4 --workers 2 \\
      --out results/method_study

The code is ``swarm_eval.method_study``; ``ros2 run swarm_eval method_study`` is the same command.
"""

import sys

from swarm_eval.method_study import main

if __name__ == '__main__':
    sys.exit(main())
