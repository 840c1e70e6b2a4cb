#!/usr/bin/env python3
"""Hardware-in-the-loop run without hardware: the formations of thesis Figs. 5.11-5.20.

  scripts/env.sh python scripts/hil_demo.py --shape all --out results/hil

The same as ``ros2 run swarm_bringup hil_demo``; what runs and what is written is
described in swarm_bringup.hil_demo_node (``--help`` lists the options).
"""

import sys

from swarm_bringup.hil_demo_node import main

if __name__ == '__main__':
    sys.exit(main())
