#!/usr/bin/env python3
"""The main job: the thesis scenario end to end through ROS 2 (``make demo``).

  scripts/env.sh python scripts/demo.py --out results/demo [--per-process]

The same as ``ros2 run swarm_bringup demo``; see swarm_bringup.demo.
"""

import sys

from swarm_bringup.demo import main

if __name__ == '__main__':
    sys.exit(main())
