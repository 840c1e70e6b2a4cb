"""Benchmark sections that run whole programs: the pybullet world
(``swarm_eval.sim_benchmark`` in a child process), headless evaluator trials, the ROS
executors (``benchmarks/bench_executor.py``) and the ROS swarm (``launch_swarm.py``)."""

from __future__ import annotations

from collections.abc import Sequence
import json
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

from swarm_eval.bench.common import log, median, PROCESS_MB, ROOT, ros_env, run_child, timed
from swarm_eval.bench.report import fmt_num
from swarm_eval.scenario import run_trial, ScenarioSpec


def bench_world(sizes: Sequence[int], repeats: int, seconds: float, seed: int) -> list[dict]:
    """swarm_eval.sim_benchmark per size, each run in a fresh process (pybullet state)."""
    rows = []
    for n in sizes:
        runs = []
        for k in range(repeats):
            proc = run_child([sys.executable, '-m', 'swarm_eval.sim_benchmark',
                              '--robots', str(n), '--seconds', str(seconds), '--terrain',
                              'rough', '--seed', str(seed + k)],
                             timeout_s=max(120.0, 20.0 * seconds * n / 50.0), env=ros_env())
            lines = [json.loads(line) for line in proc.stdout.splitlines()
                     if line.startswith('{')]
            if proc.returncode != 0 or not lines:
                raise RuntimeError('sim_benchmark.py failed: '
                                   + (proc.stderr.strip().splitlines() or ['no output'])[-1])
            runs.append(lines[-1])
        row = {'robots': n, 'agents': n, 'seconds': seconds,
               'physics_hz': runs[0]['physics_hz'], 'terrain': 'rough',
               **{key: median([r[key] for r in runs]) for key in (
                   'real_time_factor', 'cpu_real_time_factor', 'ms_per_step',
                   'physics_share', 'max_tilt_deg', 'min_ground_clearance_m')},
               'runs': runs}
        rows.append(row)
        log(f'  world {n:5d} robots: {row["real_time_factor"]:.1f}x real time at '
            f'{row["physics_hz"]:g} Hz ({row["ms_per_step"]:.2f} ms a step, physics '
            f'{100 * row["physics_share"]:.0f} %)')
    return rows


def bench_evaluator(duration_s: float, repeats: int, agents: int, beacons: int,
                    shape: str, seed: int) -> dict:
    spec = ScenarioSpec(method='bubble', shape=shape, agents=agents, beacons=beacons,
                        duration=duration_s)
    trials = []
    for k in range(repeats):
        cpu0 = time.process_time()
        wall, record = timed(run_trial, spec, seed + k)
        cpu = time.process_time() - cpu0
        sim = float(record.times[-1])
        trials.append({'seed': seed + k, 'wall_s': wall, 'cpu_s': cpu, 'sim_s': sim,
                       'settled': record.metrics.get('settling_time') is not None})
        log(f'  evaluator trial {k + 1}/{repeats}: {sim:.0f} sim-s in {wall:.1f} s wall, '
            f'{cpu:.1f} s CPU')
    wall = median([t['wall_s'] for t in trials])
    cpu = median([t['cpu_s'] for t in trials])
    cores = os.cpu_count() or 1
    return {'agents': agents, 'beacons': beacons, 'shape': shape, 'method': 'bubble',
            'duration_bound_s': duration_s, 'trials': trials,
            'wall_per_trial_s': wall, 'cpu_per_trial_s': cpu,
            'sim_s_per_trial': median([t['sim_s'] for t in trials]),
            'sim_s_per_wall_s': median([t['sim_s'] / t['wall_s'] for t in trials]),
            'sim_s_per_cpu_s': median([t['sim_s'] / t['cpu_s'] for t in trials]),
            'trials_per_min_one_process': 60.0 / wall,
            'trials_per_min_all_cores': 60.0 * cores / cpu, 'cores': cores,
            'settled_share': float(np.mean([t['settled'] for t in trials]))}


def executor_check(agents: int, duration_s: float, timeout_s: float = 600.0) -> dict:
    """Do the real agents run under each executor? launch_swarm --composed on sim time."""
    checks = {}
    for kind in ('single', 'events'):
        env = ros_env()
        env.pop('ROS_DOMAIN_ID', None)   # the launcher picks a free domain
        env['SWARM_EXECUTOR'] = kind
        with tempfile.TemporaryDirectory(prefix='run_all_exec_') as work:
            out = pathlib.Path(work)
            proc = run_child([sys.executable, str(ROOT / 'scripts' / 'launch_swarm.py'),
                              '--agents', str(agents), '--half-size', '20', '--duration',
                              str(duration_s), '--composed', '--out', str(out)],
                             timeout_s, env)
            try:
                m = json.loads((out / 'metrics.json').read_text())['trials'][0]
            except (OSError, ValueError, KeyError, IndexError):
                checks[kind] = {'error': (proc.stderr.strip().splitlines()
                                          or ['no metrics.json'])[-1]}
                continue
        heard = m.get('agents_heard')
        heard = len(heard) if isinstance(heard, list) else heard
        checks[kind] = {'agents': agents, 'duration_s': duration_s, 'agents_heard': heard,
                        'total_displacement': m.get('total_displacement'),
                        'consensus_rounds': m.get('consensus_rounds'),
                        'real_time_factor': m.get('real_time_factor'),
                        'cpu_cores_used': m.get('cpu_cores_used')}
        checks[kind]['works'] = bool(heard == agents
                                     and (m.get('total_displacement') or 0.0) > 0.0)
        log(f'  executor {kind:6s} with {agents} composed agents on sim time: heard '
            f'{heard}/{agents}, moved {fmt_num(m.get("total_displacement"), 0)} m')
    return checks


def bench_executor_section(nodes: int, rate: float, seconds: float, repeats: int,
                           check_agents: int = 0, check_duration_s: float = 15.0) -> dict:
    env = ros_env()
    runs: dict[str, list[dict]] = {}
    for _ in range(repeats):
        proc = run_child([sys.executable, str(ROOT / 'benchmarks' / 'bench_executor.py'),
                          '--nodes', str(nodes), '--rate', str(rate), '--seconds',
                          str(seconds)], timeout_s=4 * seconds + 120, env=env)
        lines = [json.loads(line) for line in proc.stdout.splitlines()
                 if line.startswith('{')]
        if proc.returncode != 0 or not lines:
            raise RuntimeError('bench_executor.py failed: '
                               + (proc.stderr.strip().splitlines() or ['no output'])[-1])
        for line in lines:
            runs.setdefault(line['executor'], []).append(line)
    result: dict = {'nodes': nodes, 'rate_hz': rate, 'seconds': seconds, 'executors': {}}
    for kind, lines in runs.items():
        result['executors'][kind] = {
            key: median([line[key] for line in lines]) for key in (
                'timer_rate_achieved', 'callbacks_per_s', 'cpu_cores',
                'cores_per_1000_cb_s')}
        log(f'  executor {kind:6s}: {result["executors"][kind]["callbacks_per_s"]:.0f} '
            f'callbacks/s, {result["executors"][kind]["cpu_cores"]:.2f} cores')
    # Which executor does composed_node get now (SWARM_EXECUTOR unset)?
    probe = ('import rclpy\n'
             'from swarm_agent import agent_node, composed_node\n'
             'assert composed_node.make_executor is agent_node.make_executor\n'
             'rclpy.init()\n'
             'print(type(composed_node.make_executor()).__name__)\n'
             'rclpy.shutdown()\n')
    env.pop('SWARM_EXECUTOR', None)
    proc = run_child([sys.executable, '-c', probe], timeout_s=120, env=env)
    result['composed_node_default'] = (proc.stdout.strip().splitlines() or ['unknown'])[-1]
    if check_agents:
        result['agents_check'] = executor_check(check_agents, check_duration_s)
    return result


def available_mb() -> float | None:
    """MemAvailable of /proc/meminfo in MB, None where there is none."""
    try:
        for line in pathlib.Path('/proc/meminfo').read_text().splitlines():
            if line.startswith('MemAvailable:'):
                return int(line.split()[1]) / 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def bench_ros(sizes: Sequence[int], duration_s: float, timeout_s: float,
              work: pathlib.Path) -> list[dict]:
    env = ros_env()
    env.pop('ROS_DOMAIN_ID', None)   # the launcher picks a free domain per run
    rows = []
    for n in sizes:
        for mode in ('per-process', 'composed'):
            out = work / f'ros_{mode}_{n}'
            cmd = [sys.executable, str(ROOT / 'scripts' / 'launch_swarm.py'), '--agents',
                   str(n), '--duration', str(duration_s), '--out', str(out)]
            if mode == 'composed':
                cmd.append('--composed')
            needed, available = n * PROCESS_MB if mode == 'per-process' else 0, available_mb()
            if available is not None and needed > 0.8 * available:
                rows.append({'agents': n, 'mode': mode, 'duration_s': duration_s,
                             'error': f'skipped: {n} processes need about {needed / 1024:.1f} '
                                      f'GB, {available / 1024:.1f} GB available'})
                log(f'  ros {mode} {n} agents: {rows[-1]["error"]}')
                continue
            log(f'  ros {mode} {n} agents: {" ".join(cmd[1:])}')
            wall, proc = timed(run_child, cmd, timeout_s, env)
            out.mkdir(parents=True, exist_ok=True)
            (out / 'launcher.log').write_text(proc.stdout + proc.stderr, encoding='utf-8')
            row: dict = {'agents': n, 'mode': mode, 'duration_s': duration_s,
                         'launcher_wall_s': wall, 'returncode': proc.returncode}
            try:
                m = json.loads((out / 'metrics.json').read_text())['trials'][0]
            except (OSError, ValueError, KeyError, IndexError):
                row['error'] = (proc.stderr.strip().splitlines() or ['no metrics.json'])[-1]
            else:
                row.update({'real_time_factor': m.get('real_time_factor'),
                            'steady_real_time_factor': m.get('steady_real_time_factor'),
                            'startup_wall_seconds': m.get('startup_wall_seconds'),
                            'cpu_cores_used': m.get('cpu_cores_used'),
                            'peak_rss_mb': (m.get('peak_rss_bytes') or 0) / 2 ** 20,
                            'peak_pss_mb': (m.get('peak_pss_bytes') or 0) / 2 ** 20,
                            'wall_seconds': m.get('wall_seconds'),
                            'outcome': m.get('outcome'),
                            'assignment_agreement': m.get('assignment_agreement'),
                            'round_agreement': m.get('round_agreement')})
            rows.append(row)
            log(f'    -> rtf {fmt_num(row.get("real_time_factor"))}, cores '
                f'{fmt_num(row.get("cpu_cores_used"))}, peak '
                f'{fmt_num(row.get("peak_pss_mb"), 0)} MB (PSS)'
                + (f', error: {row["error"]}' if 'error' in row else ''))
    return rows

