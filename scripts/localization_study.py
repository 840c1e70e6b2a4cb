#!/usr/bin/env python3
"""Localization-period study in the thesis scenario (thesis 4.2, Figs. 4.4-4.6).

  scripts/env.sh python scripts/localization_study.py --periods 3 5 8 --seeds 3 \\
      --duration 200 --noise thesis --out results/loc_thesis

The code is ``swarm_eval.localization_study``; ``ros2 run swarm_eval localization_study``
is the same command.
"""

import sys

from swarm_eval.localization_study import main

if __name__ == '__main__':
    sys.exit(main())
