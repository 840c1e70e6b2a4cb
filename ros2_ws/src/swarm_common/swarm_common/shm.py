"""Remove Fast DDS shared-memory files left behind by killed processes.

Fast DDS (the default RMW of Jazzy) keeps its shared-memory transport in files under
``/dev/shm`` (``fastrtps_<id>``, ``fastrtps_port<N>`` and their ``_el`` lock files). A
process killed while it creates one (SIGKILL from a timeout, or from its launcher dying:
launch_swarm ties its children to it) leaves a segment that never finishes initializing,
and every later participant of the same domain that opens that port spins in
``SharedMemGlobal::open_port_internal`` forever. Measured here: a 50-agent run where 37
agents and then the launcher itself hung in ``rcl_node_init`` behind 511 stale files.
Fast DDS's own remedy, ``fastdds shm clean``, does not ship in the PyPI wheels, so this
module does the same job: a file that no living process maps and that is older than a
minute cannot belong to a participant being created, and is removed.
"""

from __future__ import annotations

import os
import pathlib
import time

SHM_DIR = pathlib.Path('/dev/shm')
PREFIXES = ('fastrtps_', 'sem.fastrtps_')


def mapped_shm_files(proc: pathlib.Path = pathlib.Path('/proc')) -> set[str]:
    """Names of the /dev/shm files some living process has mapped."""
    names: set[str] = set()
    for maps in proc.glob('[0-9]*/maps'):
        try:
            text = maps.read_text(encoding='utf-8', errors='replace')
        except OSError:
            continue  # the process ended, or is not ours to read
        for line in text.splitlines():
            at = line.find('/dev/shm/')
            if at >= 0:
                names.add(line[at + len('/dev/shm/'):].split(' (deleted)')[0].strip())
    return names


def _segment(name: str) -> str:
    """The segment a file belongs to: its lock file ``X_el`` and ``sem.X_mutex`` go with X."""
    name = name.removeprefix('sem.')
    for suffix in ('_el', '_mutex'):
        name = name.removesuffix(suffix)
    return name


def clean_stale_segments(shm_dir: pathlib.Path = SHM_DIR, min_age_s: float = 60.0,
                         mapped: set[str] | None = None) -> list[str]:
    """Remove Fast DDS files of segments nobody maps, untouched for ``min_age_s``.

    Returns the names removed. Files of a segment some process maps are kept, and so
    are recent ones (a participant may be creating them right now).
    """
    if not shm_dir.is_dir():
        return []
    in_use = {_segment(n) for n in (mapped_shm_files() if mapped is None else mapped)}
    now = time.time()
    removed = []
    for path in shm_dir.iterdir():
        if not path.name.startswith(PREFIXES) or _segment(path.name) in in_use:
            continue
        try:
            if now - path.stat().st_mtime < min_age_s:
                continue
            os.unlink(path)
        except OSError:
            continue  # gone already, or another user's
        removed.append(path.name)
    return sorted(removed)
