"""Shared pieces of the benchmark suite: the issue's targets, timing helpers, children."""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math
import os
import signal
import subprocess
import time

import numpy as np

from swarm_eval.paths import repo_root

ROOT = repo_root()
SECTIONS = ('dsdv', 'trilateration', 'partition', 'cost_rows', 'assignment', 'medium',
            'world', 'evaluator', 'throughput', 'executor')
TARGET_SIZE = 1000        # the issue's per-round targets are for 1000 agents
ROUND_TARGET_S = 1.0      # assignment and cost rows under 1 s per round
EVAL_TARGET_PER_MIN = 100.0
WORLD_TARGET = (50, 20.0)  # issue 6: the bare pybullet world, 50 robots, 20x real time
# Memory of one agent_node process forked by the launcher (swarm_agent.prefork), its
# share of the pages it holds with the others (measured: 50 agents, 2.3 GB PSS in all).
PROCESS_MB = 60
# mode, agents, real-time factor (issue 9; 50 composed at 5: issue 7)
ROS_TARGETS = (('per-process', 50, 1.0), ('composed', 50, 5.0), ('composed', 100, 2.0))
# Issue 23: 100 trials a minute of its command (50 agents, 20 trials, 2 workers), 200
# agents headless at 5x real time, 100 composed at 5x, and 50 per-process agents not
# slower than the 1.37 of its day.
ISSUE23 = {'agents': 50, 'trials': 20, 'workers': 2, 'trials_per_min': 100.0,
           'large_rtf': 5.0, 'large_agents': 200,
           'ros': (('composed', 100, 5.0), ('per-process', 50, 1.37))}


class BenchError(ValueError):
    """A bad argument: one line naming it and the fix."""


# ---------------------------------------------------------------------------- helpers
def median(values: Sequence[float | None]) -> float | None:
    """Median of the finite values, None when there are none."""
    finite = [float(v) for v in values if v is not None and math.isfinite(v)]
    return float(np.median(finite)) if finite else None


def timed(fn: Callable[..., object], *args: object) -> tuple[float, object]:
    """(wall seconds, result) of one call ``fn(*args)``."""
    t0 = time.perf_counter()
    result = fn(*args)
    return time.perf_counter() - t0, result


def thesis_density_points(n: int, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """n positions uniform in a square at the chapter 4 density (50 per 100 m x 100 m)."""
    side = 100.0 * math.sqrt(n / 50.0)
    return rng.uniform(-side / 2, side / 2, (n, 2)), side


def log(text: str) -> None:
    print(text, flush=True)


def ros_env() -> dict[str, str]:
    """The environment for ROS children: this run's own domain, discovery on localhost."""
    env = dict(os.environ)
    env.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('PYTHONPATH', str(ROOT / 'scripts'))
    return env


def run_child(cmd: list[str], timeout_s: float, env: dict[str, str]
              ) -> subprocess.CompletedProcess:
    """Run ``cmd`` in its own process group; kill the whole group if it overruns."""
    proc = subprocess.Popen(cmd, cwd=str(ROOT), env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
        err += f'\nrun_all: killed after {timeout_s:.0f} s'
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)



def git(*args: str) -> str:
    """Output of ``git ARGS`` in the repository, '' when git cannot tell."""
    try:
        return subprocess.run(['git', *args], cwd=str(ROOT), capture_output=True, text=True,
                              timeout=30, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ''
