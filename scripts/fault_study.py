#!/usr/bin/env python3
"""Fault-injection study of the headless swarm (issue 10), or through ROS with --ros.

  scripts/env.sh python scripts/fault_study.py --out results/faults
  scripts/env.sh python scripts/fault_study.py --out /tmp/faults --quick

The code is ``swarm_eval.fault_study``; ``ros2 run swarm_eval fault_study`` is the same command.
"""

import sys

from swarm_eval.fault_study import main

if __name__ == '__main__':
    sys.exit(main())
