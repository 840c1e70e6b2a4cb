#!/usr/bin/env python3
"""LQR velocity loop per robot type: gains, poles, bandwidth, step response (thesis 3.2.4).

  scripts/env.sh python scripts/lqr_report.py --out results/lqr

The code is ``swarm_eval.lqr_report``; ``ros2 run swarm_eval lqr_report`` is the same command.
"""

import sys

from swarm_eval.lqr_report import main

if __name__ == '__main__':
    sys.exit(main())
