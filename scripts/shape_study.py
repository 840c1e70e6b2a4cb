#!/usr/bin/env python3
"""Generalization study: the thesis scenario on procedural shapes nobody tuned for.

  scripts/env.sh python scripts/shape_study.py --shapes 30 --seed 1 --workers 2 \\
      --out results/shape_study

The code is ``swarm_eval.shape_study_cli``; ``ros2 run swarm_eval shape_study`` is the same
command.
"""

import sys

from swarm_eval.shape_study_cli import main

if __name__ == '__main__':
    sys.exit(main())
