#!/usr/bin/env python3
"""Speed of the bare pybullet world (swarm_sim.world, thesis 4.1), without ROS; one JSON line.

  scripts/env.sh python scripts/sim_benchmark.py --robots 50 --terrain rough

The code is ``swarm_eval.sim_benchmark``; ``ros2 run swarm_eval sim_benchmark`` is the same
command.
"""

import sys

from swarm_eval.sim_benchmark import main

if __name__ == '__main__':
    sys.exit(main())
