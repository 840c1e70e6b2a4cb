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


def _start(processes, out: pathlib.Path, until: int = 7) -> tuple[subprocess.Popen, set[int]]:
    """A per-process 4-agent run; returns once ``until`` of its processes have started
    (all 7: sim, mission, the fork server and the 4 agents it forks)."""
    proc = processes.python(str(LAUNCH), '--agents', '4', '--beacons', '3',
                            '--shape', str(SHAPE), '--half-size', '15', '--duration', '600',
                            '--out', str(out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60.0
    kids: set[int] = set()
    while time.monotonic() < deadline and len(kids) < until:
        time.sleep(0.05)
        assert proc.poll() is None, 'the launcher stopped early'
        kids = _descendants(proc.pid)
    assert len(kids) >= until, f'only {len(kids)} processes started'
    return proc, kids


def _holding_files_in(folder: pathlib.Path) -> set[int]:
    """Processes with a file open below ``folder``: every node keeps its log there, so
    this finds an agent forked after its launcher died, which no process tree shows."""
    found = set()
    for fd_dir in pathlib.Path('/proc').glob('[0-9]*/fd'):
        try:
            if any(os.readlink(fd).startswith(str(folder)) for fd in fd_dir.iterdir()):
                found.add(int(fd_dir.parent.name))
        except OSError:
            continue
    return found


def _wait_gone(pids: set[int], timeout: float = 15.0) -> set[int]:
    deadline = time.monotonic() + timeout
    while _alive(pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    return _alive(pids)


@pytest.mark.parametrize('until', [3, 5, 7])
def test_sigkilled_launcher_leaves_no_node(processes, tmp_path, until):
    """SIGKILL cannot be caught: the nodes (each in its own session, out of reach of the
    launcher's process group) must still go (PR_SET_PDEATHSIG), and so must the fork
    server and its resource tracker, however far the start had come: killed while the
    fork server imports (3, 5 processes), fork requests still queued then must not start
    agents that nothing stops."""
    out = tmp_path / 'kill'
    proc, kids = _start(processes, out, until)
    proc.kill()
    proc.wait(timeout=5)
    assert not _wait_gone(kids, timeout=30.0), 'orphaned nodes'
    time.sleep(2.0)      # a queued fork request would have started its agent by now
    assert not _wait_gone(_holding_files_in(out), timeout=15.0), 'agents started orphaned'


def test_sigterm_stops_the_run_like_ctrl_c(processes, tmp_path):
    """SIGTERM (a supervisor, a timeout) stops every node and still writes the metrics."""
    out = tmp_path / 'term'
    proc, kids = _start(processes, out)
    os.kill(proc.pid, signal.SIGTERM)
    assert proc.wait(timeout=60) is not None
    assert not _wait_gone(kids)
    metrics = json.loads((out / 'metrics.json').read_text())['trials'][0]
    assert metrics['outcome'] == 'interrupted'


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def test_sigint_stops_a_launcher_started_with_sigint_ignored(processes, tmp_path):
    """A background job of a shell without job control (`launch_swarm.py ... &` in a
    script, nohup) inherits SIGINT ignored; kill -INT must still stop the run and every
    node, as Ctrl-C does."""
    out = tmp_path / 'bg'
    proc = processes.python(str(LAUNCH), '--agents', '4', '--beacons', '3', '--composed',
                            '--shape', str(SHAPE), '--half-size', '15', '--duration', '600',
                            '--out', str(out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, preexec_fn=_ignore_sigint)
    deadline = time.monotonic() + 60.0
    kids: set[int] = set()
    while time.monotonic() < deadline and len(kids) < 3:   # sim, mission, agents
        time.sleep(0.05)
        assert proc.poll() is None, 'the launcher stopped early'
        kids = _descendants(proc.pid)
    os.kill(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=60) is not None, 'SIGINT ignored'
    assert not _wait_gone(kids)
    assert json.loads((out / 'metrics.json').read_text())['trials'][0]['outcome'] \
        == 'interrupted'
