#!/usr/bin/env python3
"""Start a whole swarm through ROS 2 from one command, watch it, and report.

  scripts/env.sh python scripts/launch_swarm.py --agents 50 --beacons 8 \\
      --method bubble --shape circle_314 --duration 300 --out results/swarm

The same as ``ros2 run swarm_bringup launch_swarm``; the options, outputs and the
processes started are described in swarm_bringup.supervisor_node (``--help`` lists the
options). ``parse_args``, ``validate`` and ``LaunchError`` are the checks of a run
(swarm_bringup.scenario), importable from here for the study scripts.
"""

import sys

from swarm_bringup.scenario import LaunchError, parse_args, validate  # noqa: F401
from swarm_bringup.supervisor_node import main

if __name__ == '__main__':
    sys.exit(main())
