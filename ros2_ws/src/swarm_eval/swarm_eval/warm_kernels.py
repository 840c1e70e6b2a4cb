"""Compile every kernel of the swarm packages once for this machine (numba's disk cache).

  scripts/env.sh python -m swarm_eval.warm_kernels

``make bootstrap`` runs this after it builds the workspace. numba keeps machine code
beside the sources, but only for kernels some process has called. Without this step the
first processes of a fresh install compile the kernels they call, each on its own and
at the same time: a second or more per kernel. Started cold, the five agents of the
hardware-in-the-loop demo left its emulated world without CPU for 3-6 s.

Every module of the packages is imported except the ``*_node`` modules (rclpy nodes,
which define no kernel), then ``swarm_common.jit.warm`` compiles each registered
kernel, or loads it from the cache, on its example arguments.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

from swarm_common import jit

PACKAGES = ('swarm_common', 'swarm_mission', 'swarm_agent', 'swarm_sim', 'swarm_bridge',
            'swarm_bringup', 'swarm_eval')


def kernel_modules() -> list[str]:
    """The modules of ``PACKAGES`` to import, nodes left out (module docstring)."""
    names = []
    for package in PACKAGES:
        path = importlib.import_module(package).__path__
        names.extend(f'{package}.{m.name}' for m in pkgutil.iter_modules(path)
                     if not m.ispkg and not m.name.endswith('_node'))
    return names


def main(argv: list[str] | None = None) -> int:
    """Import the modules, compile their kernels; one line of what was done."""
    skipped = []
    for name in kernel_modules():
        try:
            importlib.import_module(name)
        except ImportError as exc:          # an optional dependency that is not installed
            skipped.append(f'{name} ({exc})')
    ready = jit.warm()
    print(f'warm_kernels: {ready} of {jit.registered()} kernels compiled and cached'
          + (f'; not imported: {", ".join(skipped)}' if skipped else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
