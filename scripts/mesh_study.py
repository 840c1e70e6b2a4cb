#!/usr/bin/env python3
"""Monte Carlo mesh study: bubble packing vs randomized fractals over seeds (thesis 4.3.1, 4.3.5).

  scripts/env.sh python scripts/mesh_study.py --seeds 20 --out results/mesh_study

The code is ``swarm_eval.mesh_study``; ``ros2 run swarm_eval mesh_study`` is the same command.
"""

import sys

from swarm_eval.mesh_study import main

if __name__ == '__main__':
    sys.exit(main())
