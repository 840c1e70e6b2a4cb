"""Child processes of a run: started from a launch plan, watched, and all stopped.

``Children`` starts each process of a plan (swarm_bringup.launch_plan) in its own process
group with its log in ``log_dir`` (exec'd, or forked from a server that has imported the
node module once: swarm_agent.prefork), tells which one crashed, reads their CPU time
and memory from /proc, and stops them all (SIGINT, then SIGKILL after a grace period).
A process whose plan entry has ``respawn`` (the agents, the mission node) and that exits
on its own is started again ``RESPAWN_DELAY_S`` later, at most ``RESPAWN_RETRIES`` times,
with one line on stderr each time; its earlier log is kept as ``NAME.runK.log``. Only a
process out of restarts, or one that refused its configuration (status 2), counts as
crashed. Processes the run kills (``kill``: a removed
robot) and stopped ones are never restarted.
Every child dies with the launcher however the launcher dies (``die_with_parent``), so
no orphans are left.
"""

from __future__ import annotations

from collections.abc import Iterable
import functools
import os
import pathlib
import signal
import subprocess
import sys
import time

from swarm_agent.prefork import die_with_parent, ForkedProcess, ForkServer
from swarm_bringup.launch_plan import (
    NodeSpec,
    RESPAWN_DELAY_S,
    RESPAWN_RETRIES,
    ros_arguments,
)

# A node that refused its parameters or files (swarm_common.ros_support.run_node: one
# line, status 2) would refuse them again: its exit is a crash, not restarted.
EXIT_BAD_INPUT = 2


def stop_groups(procs: Iterable[subprocess.Popen], grace: float) -> None:
    """SIGINT to the process group of every process still running, then SIGKILL to the
    groups still alive ``grace`` seconds later (each process leads its own group)."""
    procs = list(procs)
    for proc in procs:
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
    deadline = time.monotonic() + grace
    for proc in procs:
        try:
            proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(timeout=5)

class Children:
    """Child processes, each in its own process group, with logs in out/logs."""

    def __init__(self, log_dir: pathlib.Path, env: dict[str, str],
                 cwd: str | None = None) -> None:
        self.log_dir = log_dir
        self.env = env
        # The children resolve relative paths (a shape file) as the launcher did.
        self.cwd = cwd or os.getcwd()
        self.procs: dict[str, subprocess.Popen | ForkedProcess] = {}
        self.expected_exit: set[str] = set()
        self._forks: ForkServer | None = None
        self.specs: dict[str, NodeSpec] = {}
        self.respawns: dict[str, int] = {}       # name -> restarts so far
        self._died: dict[str, float] = {}        # name -> when its exit was seen

    def start(self, name: str, args: list[str]) -> None:
        log = open(self.log_dir / f'{name}.log', 'w', encoding='utf-8')  # noqa: SIM115
        self.procs[name] = subprocess.Popen(
            [sys.executable, *args], stdout=log, stderr=subprocess.STDOUT, env=self.env,
            cwd=self.cwd, start_new_session=True,
            preexec_fn=functools.partial(die_with_parent, os.getpid()))

    def fork(self, name: str, module: str, args: list[str]) -> None:
        """Like ``start`` for ``python -m module args``, forked from a server that has
        imported the module once (swarm_agent.prefork: 50 agents came up in 30 s of
        imports on two cores when each was exec'd)."""
        if self._forks is None:
            self._forks = ForkServer([module])
        self.procs[name] = self._forks.start(name, module, args,
                                             str(self.log_dir / f'{name}.log'), self.env,
                                             self.cwd)

    def run(self, spec: NodeSpec) -> None:
        """Start one process of a launch plan under its ``process`` name."""
        self.specs[spec.process] = spec
        if spec.fork:
            self.fork(spec.process, spec.module, ros_arguments(spec))
        else:
            self.start(spec.process, ['-m', spec.module, *ros_arguments(spec)])

    def kill(self, name: str) -> None:
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None:
            self.expected_exit.add(name)
            os.killpg(proc.pid, signal.SIGKILL)

    def crashed(self) -> str | None:
        """The first process that exited on its own and will not be started again (None:
        none); restarts the respawned ones that are due (module docstring)."""
        for name, proc in list(self.procs.items()):
            if proc.poll() is None or name in self.expected_exit:
                continue
            spec = self.specs.get(name)
            if spec is None or not spec.respawn or proc.returncode == EXIT_BAD_INPUT or \
                    self.respawns.get(name, 0) >= RESPAWN_RETRIES:
                return name
            died = self._died.setdefault(name, time.monotonic())
            if time.monotonic() - died >= RESPAWN_DELAY_S:
                self._respawn(name, spec, proc.returncode)
        return None

    def _respawn(self, name: str, spec: NodeSpec, code: int | None) -> None:
        count = self.respawns[name] = self.respawns.get(name, 0) + 1
        del self._died[name]
        log = self.log_dir / f'{name}.log'
        if log.exists():
            log.rename(self.log_dir / f'{name}.run{count}.log')
        self.run(spec)
        # The new run's log exists when the line below says it started (a forked child
        # opens it itself, later); the child truncates this empty file.
        log.touch()
        print(f'launch_swarm: {name} exited with code {code}; started again '
              f'({count}/{RESPAWN_RETRIES})', file=sys.stderr, flush=True)

    def tail(self, name: str, lines: int = 15) -> str:
        text = (self.log_dir / f'{name}.log').read_text(encoding='utf-8', errors='replace')
        return '\n'.join(text.splitlines()[-lines:])

    def cpu_seconds(self) -> float:
        """CPU time of all children (user + system), from /proc, while they run."""
        total = 0.0
        tick = os.sysconf('SC_CLK_TCK')
        for proc in self.procs.values():
            try:
                fields = pathlib.Path(f'/proc/{proc.pid}/stat').read_text().split(')')[1].split()
                total += (int(fields[11]) + int(fields[12])) / tick
            except (OSError, IndexError, ValueError):
                pass
        return total

    def pss_bytes(self) -> int:
        """Current proportional set size of all children: resident memory with each page
        shared by k processes counted 1/k times in each (forked agents share their
        modules: 2.3 GB for 50 agents whose resident sizes add up to 6.3 GB). Reading it
        makes the kernel walk every page table (about 0.4 s for 50 agents under load),
        so it is sampled rarely. Falls back to the resident size without smaps_rollup."""
        total = 0
        for proc in self.procs.values():
            try:
                text = pathlib.Path(f'/proc/{proc.pid}/smaps_rollup').read_text()
                total += next(int(line.split()[1]) * 1024 for line in text.splitlines()
                              if line.startswith('Pss:'))
            except (OSError, ValueError, IndexError, StopIteration):
                total += self._rss_of(proc.pid)
        return total

    @staticmethod
    def _rss_of(pid: int) -> int:
        try:
            for line in pathlib.Path(f'/proc/{pid}/status').read_text().splitlines():
                if line.startswith('VmRSS:'):
                    return int(line.split()[1]) * 1024
        except (OSError, ValueError, IndexError):
            pass
        return 0

    def rss_bytes(self) -> int:
        """Current resident memory of all children (shared pages counted in each)."""
        return sum(self._rss_of(proc.pid) for proc in self.procs.values())

    def stop_all(self, grace: float = 5.0) -> None:
        self.expected_exit.update(name for name, proc in self.procs.items()
                                  if proc.poll() is None)
        stop_groups(self.procs.values(), grace)
