"""A stand-in node module for tests/unit/test_prefork.py: reports what it was given."""

from __future__ import annotations

import os
import sys
import time


def main(argv: list[str]) -> None:
    print(f'argv={argv[1:]} env={os.environ.get("PREFORK_PROBE")} '
          f'own_session={os.getsid(0) == os.getpid()} cwd={os.getcwd()}', flush=True)
    print('to stderr', file=sys.stderr, flush=True)
    if '--fail' in argv:
        sys.exit(3)
    if '--sleep' in argv:
        time.sleep(60.0)
