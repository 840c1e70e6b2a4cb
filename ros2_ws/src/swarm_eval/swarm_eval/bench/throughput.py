"""Benchmark section ``throughput``: the headless evaluator's targets of issue 23.

- the issue's command, ``scripts/evaluate.py --method bubble --shape circle_314 --agents 50
  --trials 20 --workers 2``, run as a user runs it (a child process, start-up, workers
  and every trial to its end included): trials per minute, and how many settled;
- a large swarm headless (``run_trial``, 200 agents on the thesis circle scaled by 2 so
  that their density stays the thesis's, bounded to a number of simulated seconds):
  simulated seconds per wall second.
"""

from __future__ import annotations

import json
import pathlib
import sys
import tempfile
import time

from swarm_eval.bench.common import ISSUE23, log, ROOT, ros_env, run_child
from swarm_eval.scenario import run_trial, ScenarioSpec


def bench_issue_command(agents: int, trials: int, workers: int, seed: int,
                        duration_s: float | None = None) -> dict:
    """The issue's command, timed from start to exit; ``duration_s`` bounds each trial
    (None: the command as the issue gives it, every trial to its end)."""
    with tempfile.TemporaryDirectory(prefix='run_all_eval_') as work:
        out = pathlib.Path(work) / 'out'
        cmd = [sys.executable, str(ROOT / 'scripts' / 'evaluate.py'), '--method', 'bubble',
               '--shape', 'circle_314', '--agents', str(agents), '--trials', str(trials),
               '--workers', str(workers), '--seed', str(seed), '--out', str(out)]
        if duration_s is not None:
            cmd += ['--duration', f'{duration_s:g}']
        start = time.perf_counter()
        proc = run_child(cmd, timeout_s=600.0 + 120.0 * trials, env=ros_env())
        wall = time.perf_counter() - start
        try:
            rows = [json.loads(line) for line in
                    (out / 'trials.jsonl').read_text(encoding='utf-8').splitlines() if line]
        except OSError:
            rows = []
    if proc.returncode != 0 or len(rows) != trials:
        raise RuntimeError('evaluate.py failed: '
                           + (proc.stderr.strip().splitlines() or ['no trials written'])[-1])
    settled = sum(r.get('settling_time') is not None for r in rows)
    shown = ['scripts/evaluate.py', *cmd[2:cmd.index('--out')]]   # as the docs give it
    row = {'command': ' '.join(shown), 'agents': agents,
           'trials': trials, 'workers': workers, 'wall_s': wall,
           'trials_per_min': 60.0 * trials / wall, 'settled': settled,
           'trial_wall_sum_s': sum(r['wall_seconds'] for r in rows),
           'duration_bound_s': duration_s}
    log(f"  the issue's command: {trials} trials in {wall:.1f} s, "
        f'{row["trials_per_min"]:.1f} a minute, {settled} settled')
    return row


def bench_large_swarm(agents: int, duration_s: float, seed: int) -> dict:
    """One trial of ``agents`` on the thesis circle scaled to the thesis density."""
    scale = (agents / 50.0) ** 0.5
    spec = ScenarioSpec(method='bubble', shape='circle_314', shape_scale=scale, agents=agents,
                        duration=duration_s)
    cpu0, start = time.process_time(), time.perf_counter()
    record = run_trial(spec, seed)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
    sim = float(record.times[-1])
    row = {'agents': agents, 'shape_scale': scale, 'duration_bound_s': duration_s,
           'sim_s': sim, 'wall_s': wall, 'cpu_s': cpu, 'real_time_factor': sim / wall,
           'cpu_real_time_factor': sim / cpu}
    log(f'  {agents} agents headless: {sim:.0f} sim-s in {wall:.1f} s wall, '
        f'{row["real_time_factor"]:.2f}x real time')
    return row


def bench_throughput(issue_trials: int, issue_workers: int, large_agents: int,
                     large_duration_s: float, seed: int, quick: bool) -> dict:
    """The section: the issue's command (--quick: 10 agents, 3 sim-s a trial) and the
    large swarm."""
    command = (bench_issue_command(10, issue_trials, issue_workers, seed, 3.0) if quick
               else bench_issue_command(ISSUE23['agents'], issue_trials, issue_workers,
                                        seed))
    return {'issue_command': command,
            'large_swarm': bench_large_swarm(large_agents, large_duration_s, seed)}
