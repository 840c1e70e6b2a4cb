#!/usr/bin/env python3
"""Partition a formation shape into typed goal states (thesis 3.2.2.1) and measure the mesh.

  scripts/env.sh python scripts/partition.py --method bubble --shape thesis_shape_1 \\
      --agents 50 --types 1:20,2:20,3:10 --seed 0 --out results/partition

The code is ``swarm_eval.partition_report``; ``ros2 run swarm_eval partition`` is the same command.
"""

import sys

from swarm_eval.partition_report import main

if __name__ == '__main__':
    sys.exit(main())
