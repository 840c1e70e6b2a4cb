#!/usr/bin/env python3
"""How fast a restarted agent is back in its neighbours' route tables (docs/restarts.md).

  scripts/env.sh python scripts/rejoin_study.py --restarts 10

The code is ``swarm_eval.rejoin_study``.
"""

import sys

from swarm_eval.rejoin_study import main

if __name__ == '__main__':
    sys.exit(main())
