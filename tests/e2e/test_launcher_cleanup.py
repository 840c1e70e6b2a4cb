"""A launcher that dies, however it dies, takes its nodes with it (no orphans)."""

from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'scripts' / 'launch_swarm.py'
SHAPE = ROOT / 'tests' / 'data' / 'square_8m.json'

pytestmark = [pytest.mark.e2e]


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid``: the per-process agents are forked by the launcher's
    fork server (swarm_agent.prefork), so they are its grandchildren."""
    found: set[int] = set()
    frontier = [pid]
    while frontier:
        out = subprocess.run(['ps', '--ppid', ','.join(map(str, frontier)), '-o', 'pid='],
                             capture_output=True, text=True).stdout
        frontier = [int(p) for p in out.split() if int(p) not in found]
        found.update(frontier)
    return found


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for pid in pids:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            continue
        alive.add(pid)
    return alive


def _start(processes, out: pathlib.Path) -> tuple[subprocess.Popen, set[int]]:
    """A per-process 4-agent run; returns once its processes (sim, mission, the fork
    server and the 4 agents it forks) are all started."""
    proc = processes.python(str(LAUNCH), '--agents', '4', '--beacons', '3',
                            '--shape', str(SHAPE), '--half-size', '15', '--duration', '600',
                            '--out', str(out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60.0
    kids: set[int] = set()
    while time.monotonic() < deadline and len(kids) < 7:
        time.sleep(0.5)
        assert proc.poll() is None, 'the launcher stopped early'
        kids = _descendants(proc.pid)
    assert len(kids) >= 7, f'only {len(kids)} processes started'
    return proc, kids


def _wait_gone(pids: set[int], timeout: float = 15.0) -> set[int]:
    deadline = time.monotonic() + timeout
    while _alive(pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    return _alive(pids)


def test_sigkilled_launcher_leaves_no_node(processes, tmp_path):
    """SIGKILL cannot be caught: the nodes (each in its own session, out of reach of the
    launcher's process group) must still go (PR_SET_PDEATHSIG). A benchmark that killed
    an overrunning launcher once left 100 agent processes running for 20 minutes."""
    proc, kids = _start(processes, tmp_path / 'kill')
    proc.kill()
    proc.wait(timeout=5)
    assert not _wait_gone(kids), 'orphaned nodes'


def test_sigterm_stops_the_run_like_ctrl_c(processes, tmp_path):
    """SIGTERM (a supervisor, a timeout) stops every node and still writes the metrics."""
    out = tmp_path / 'term'
    proc, kids = _start(processes, out)
    os.kill(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=60) is not None
    assert not _wait_gone(kids)
    metrics = json.loads((out / 'metrics.json').read_text())['trials'][0]
    assert metrics['outcome'] == 'interrupted'
