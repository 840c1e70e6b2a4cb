#!/usr/bin/env python3
"""The Measured table (docs/measured.md): run its rows' commands, render the page from their files.

  scripts/env.sh python scripts/measure.py run --out results/measured [--rows faults,mesh]
  scripts/env.sh python scripts/measure.py render results/measured --write docs/measured.md

The code is ``swarm_eval.measured``; ``ros2 run swarm_eval measure`` is the same command.
"""

import sys

from swarm_eval.measured import main

if __name__ == '__main__':
    sys.exit(main())
