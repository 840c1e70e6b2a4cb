#!/usr/bin/env python3
"""The benchmark suite in one command: writes docs/benchmarks.md and docs/benchmarks.json.

Every figure comes from the package code (no algorithm is re-implemented here); timings
are medians of --repeats runs, per swarm size of --sizes:

- dsdv:          convergence of the real DsdvRouters after a link break and from a cold
                 start, in simulated seconds (benchmarks/bench_dsdv.py ``bench``; one
                 random geometric graph per repeat, --dsdv-repeats, since the figure is
                 deterministic for a graph and a 1000-agent run takes minutes);
- trilateration: one localization round of the swarm (``Localizer.localize`` of every
                 agent with four beacons in radio range);
- partition:     bubble packing and randomized fractals of the thesis circle scaled to
                 the swarm (benchmarks/bench_partition.py ``bench``);
- cost_rows:     visibility graph + Dijkstra (``VisibilityGraph.cost_row``) in the thesis
                 workspace with its four obstacles scaled to the swarm: one agent's row
                 (median agent in a steady round; worst agent in the first round after new
                 goals, fresh graph) and every agent's row (what one process running the
                 whole swarm pays per round);
- assignment:    the Hungarian consensus ``assign`` over every agent's row (all types);
- medium:        one step of the radio medium (``RadioMedium.update_positions``: links
                 with line of sight; then one 24-byte broadcast per agent transmitted and
                 delivered);
- world:         the bare pybullet world of swarm_sim (scripts/sim_benchmark.py in a
                 child process: --world-sizes robots of the three types on rough terrain
                 in the +/-50 m workspace, DIRECT mode, its default physics rate, the
                 state read after every step): real-time factor (issue 6's target: 20x
                 with 50 robots);
- evaluator:     whole headless trials of the thesis scenario (scripts/evaluate.py
                 ``run_trial``: 50 agents, 8 beacons, circle_314, bubble) bounded to
                 --eval-duration simulated seconds: wall and CPU seconds per trial, sim
                 seconds per wall second, trials per minute;
- executor:      benchmarks/bench_executor.py (SingleThreaded vs EventsExecutor, 50
                 nodes at 50 Hz) in a child process, and which executor composed_node gets;
- ros (--ros):   scripts/launch_swarm.py per-process and --composed at --ros-sizes agents
                 for --ros-duration simulated seconds; real-time factor, CPU cores and
                 peak memory from its metrics.json. Off by default: slow (minutes).

The issue's targets are printed and written as met / missed. The figures depend on the
machine and on what else runs on it: the JSON records core count, load averages at the
start and the end, Python version, date and git commit.

  scripts/env.sh python benchmarks/run_all.py                 # the suite, into docs/
  scripts/env.sh python benchmarks/run_all.py --sizes 50,200 --repeats 1 --out /tmp/bench
  scripts/env.sh python benchmarks/run_all.py --ros --ros-sizes 20,50,100 --ros-duration 30
  scripts/env.sh python benchmarks/run_all.py --sizes 10 --repeats 1 --quick --out /tmp/q
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import datetime
import json
import math
import os
import pathlib
import platform
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
SECTIONS = ('dsdv', 'trilateration', 'partition', 'cost_rows', 'assignment', 'medium',
            'world', 'evaluator', 'executor')
TARGET_SIZE = 1000        # the per-round targets are for 1000 agents
ROUND_TARGET_S = 1.0      # assignment and cost rows under 1 s per round
EVAL_TARGET_PER_MIN = 100.0
WORLD_TARGET = (50, 20.0)  # issue 6: the bare pybullet world, 50 robots, 20x real time
# Memory of one agent_node process forked by the launcher (swarm_agent.prefork), its
# share of the pages it holds with the others (measured: 50 agents, 2.3 GB PSS in all).
PROCESS_MB = 60
# mode, agents, real-time factor (issue 9; 50 composed at 5: issue 7)
ROS_TARGETS = (('per-process', 50, 1.0), ('composed', 50, 5.0), ('composed', 100, 2.0))


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


# ---------------------------------------------------------------------------- sections
def bench_dsdv_section(sizes: Sequence[int], repeats: int, limit_s: float) -> list[dict]:
    import bench_dsdv

    rows = []
    for n in sizes:
        runs = [bench_dsdv.bench(n, seed, limit_s) for seed in range(repeats)]
        row = {'agents': n, 'graphs': len(runs),
               'diameter': median([r['diameter'] for r in runs]),
               'mean_degree': median([r['mean_degree'] for r in runs]),
               'wall_s': median([r['wall_s'] for r in runs]),
               'full_dump_period_s': bench_dsdv.DsdvConfig().full_dump_period_s}
        for key in ('cold_start_s', 'link_break_s', 'link_addition_s'):
            row[key] = median([r.get(key) for r in runs])
            row[key[:-2] + '_periods'] = (None if row[key] is None else
                                          row[key] / row['full_dump_period_s'])
            row[key[:-2] + '_not_converged'] = sum(r.get(key) is None for r in runs)
        for key in ('routing_bytes_per_s_per_agent',
                    'routing_bytes_per_s_per_agent_with_overhead', 'frames_per_s_per_agent'):
            row[key] = median([r[key] for r in runs])
        rows.append(row)
        log(f'  dsdv {n:5d} agents: link break {row["link_break_s"]} s, cold start '
            f'{row["cold_start_s"]} s (simulated), wall {row["wall_s"]:.1f} s per graph')
    return rows


def localization_round(agents: Sequence, heard: Sequence) -> list:
    """Every agent's localization tick (t = 3 s) with the beacons it hears."""
    return [a.localize(3.0, h) for a, h in zip(agents, heard)]


def bench_trilateration(sizes: Sequence[int], repeats: int, seed: int,
                        beacons_per_agent: int = 4) -> list[dict]:
    from swarm_agent.localization import LocalizationConfig, Localizer
    from swarm_sim.medium import MediumConfig

    radio = MediumConfig()
    rows = []
    for n in sizes:
        rng = np.random.default_rng(seed)
        truth, _ = thesis_density_points(n, rng)
        # Each agent hears `beacons_per_agent` beacons somewhere within radio range.
        angle = rng.uniform(0, 2 * np.pi, (n, beacons_per_agent))
        dist = rng.uniform(2.0, radio.range_m, (n, beacons_per_agent))
        beacons = truth[:, None, :] + dist[..., None] * np.stack(
            [np.cos(angle), np.sin(angle)], axis=-1)
        ranges = dist + rng.normal(0.0, radio.range_noise_std, dist.shape)
        heard = [[(beacons[i, k], ranges[i, k], radio.range_noise_std)
                  for k in range(beacons_per_agent)] for i in range(n)]
        config = LocalizationConfig()
        localization_round([Localizer(config, p) for p in truth], heard)   # warm-up
        times, localized = [], []
        for _ in range(repeats):
            agents = [Localizer(config, truth[i] + rng.normal(0.0, 1.0, 2)) for i in range(n)]
            wall, modes = timed(localization_round, agents, heard)
            times.append(wall)
            localized.append(float(np.mean([int(m) == 0 for m in modes])))
        row = {'agents': n, 'beacons_per_agent': beacons_per_agent,
               'round_s': median(times), 'per_agent_s': median(times) / n,
               'localized_share': median(localized)}
        rows.append(row)
        log(f'  trilateration {n:5d} agents: round {row["round_s"] * 1e3:.1f} ms '
            f'({row["per_agent_s"] * 1e6:.0f} us per agent)')
    return rows


def bench_partition_section(sizes: Sequence[int], repeats: int) -> list[dict]:
    import bench_partition

    rows = []
    for n in sizes:
        for row in bench_partition.bench(n, 'circle_314', repeats):
            rows.append(row)
            log(f'  partition {row["method"]:8s} {n:5d} agents: {row["seconds_median"]:.2f} s')
    return rows


def cost_setup(n: int, seed: int) -> dict:
    """Thesis workspace scaled to n agents: shape, obstacles, goals, agent starts."""
    from swarm_mission.partition import partition
    from swarm_mission.robot_types import default_type_counts, load_robot_types
    from swarm_mission.shapes import load_shape
    from swarm_sim.fleet import random_fleet

    scale = math.sqrt(n / 50.0)
    shape = load_shape('thesis_workspace').scaled(scale)
    types = load_robot_types()
    radii = {t: r.coverage_radius for t, r in types.items()}
    counts = default_type_counts(n)
    rng = np.random.default_rng(seed)
    goals = partition(shape, counts, radii, 'bubble', seed=seed).goals
    fleet = random_fleet(counts, 0, rng, half_size=50.0 * scale,
                         obstacles=list(shape.obstacles))
    return {'shape': shape, 'radii': radii, 'goals': goals, 'fleet': fleet}


def all_cost_rows(by_type: dict, goal_xy: np.ndarray
                  ) -> tuple[dict, list[float], list[tuple[float, int, int]]]:
    """Every agent's row, as ``assign`` takes them, and the time of each row.

    ``by_type``: type -> (grown obstacles, graph, goal columns, starts, agent ids).
    """
    rows, per_agent, worst = {}, [], []
    for t, (_, graph, cols, starts, ids) in by_type.items():
        for agent, start in zip(ids, starts):
            wall, costs = timed(graph.cost_row, start, goal_xy[cols])
            full = np.full(len(goal_xy), np.inf)
            full[cols] = costs
            rows[agent] = (t, full)
            per_agent.append(wall)
            worst.append((wall, t, agent))
    return rows, per_agent, worst


def bench_costs(sizes: Sequence[int], repeats: int, seed: int
                ) -> tuple[list[dict], list[dict]]:
    """Cost rows and the Hungarian assignment over them, per size."""
    from swarm_agent.assignment import assign
    from swarm_agent.costs import VisibilityGraph
    from swarm_agent.free_space import grow_obstacles

    cost_rows, assignment_rows = [], []
    for n in sizes:
        s = cost_setup(n, seed)
        obstacles = list(s['shape'].obstacles)
        goal_types = np.array([g.type for g in s['goals']])
        goal_ids = np.array([g.id for g in s['goals']])
        goal_xy = np.array([[g.x, g.y] for g in s['goals']])
        by_type = {}
        build_times = []
        for t in sorted({r.type for r in s['fleet']}):
            grown = grow_obstacles(obstacles, s['radii'][t])
            wall, graph = timed(VisibilityGraph, grown)
            build_times.append(wall)
            cols = np.flatnonzero(goal_types == t)
            starts = np.array([[r.x, r.y] for r in s['fleet'] if r.type == t])
            ids = [r.id for r in s['fleet'] if r.type == t]
            by_type[t] = (grown, graph, cols, starts, ids)
        # first round: every graph builds its goal-vertex table
        first_wall, (rows, _, worst) = timed(all_cost_rows, by_type, goal_xy)
        steady, agent_times = [], []
        for _ in range(repeats):
            wall, (rows, per_agent, _) = timed(all_cost_rows, by_type, goal_xy)
            steady.append(wall)
            agent_times.extend(per_agent)
        # The slowest agent of the first round, again on a fresh graph of its own (every
        # brain has its own VisibilityGraph): its first row after new goals.
        _, worst_type, worst_agent = max(worst)
        grown, _, cols, starts, ids = by_type[worst_type]
        start = starts[ids.index(worst_agent)]
        first_rows = []
        for _ in range(repeats):
            graph = VisibilityGraph(grown)
            first_rows.append(timed(graph.cost_row, start, goal_xy[cols])[0])
        row = {'agents': n, 'obstacles': len(obstacles), 'goals': len(goal_xy),
               'graph_build_s': median(build_times),
               'row_median_s': median(agent_times),
               'row_worst_first_s': median(first_rows),
               'all_rows_s': median(steady), 'all_rows_first_round_s': first_wall,
               'unreachable_share': float(np.mean([
                   (~np.isfinite(r[1][goal_types == r[0]])).mean() for r in rows.values()]))}
        cost_rows.append(row)
        log(f'  cost rows {n:5d} agents: one row {row["row_median_s"] * 1e3:.2f} ms (worst '
            f'first {row["row_worst_first_s"] * 1e3:.1f} ms), all rows '
            f'{row["all_rows_s"]:.3f} s')
        result = assign(rows, goal_types, goal_ids)   # warm-up
        times = [timed(assign, rows, goal_types, goal_ids)[0] for _ in range(repeats)]
        t1 = min(by_type)
        one_type = {a: r for a, r in rows.items() if r[0] == t1}
        times_one = [timed(assign, one_type, goal_types, goal_ids)[0] for _ in range(repeats)]
        arow = {'agents': n, 'assign_all_s': median(times),
                'assign_one_type_s': median(times_one), 'one_type_agents': len(one_type),
                'assigned_share': len(result) / n}
        assignment_rows.append(arow)
        log(f'  assignment {n:5d} agents: {arow["assign_all_s"] * 1e3:.1f} ms (one type, '
            f'{len(one_type)} agents: {arow["assign_one_type_s"] * 1e3:.1f} ms)')
    return cost_rows, assignment_rows


def send_and_deliver(medium, packets: Sequence, t: float) -> int:
    """Transmit every packet at ``t``; deliver everything due by t + 0.5 s; count it."""
    for packet in packets:
        medium.transmit(t, packet)
    return len(medium.deliver(t + 0.5))


def bench_medium(sizes: Sequence[int], repeats: int, seed: int,
                 payload_bytes: int = 24) -> list[dict]:
    from swarm_agent.packet import BROADCAST, Kind, Packet
    from swarm_mission.shapes import load_shape
    from swarm_sim.medium import MediumConfig, RadioMedium

    rows = []
    for n in sizes:
        rng = np.random.default_rng(seed)
        positions, _ = thesis_density_points(n, rng)
        obstacles = list(load_shape('thesis_workspace').scaled(math.sqrt(n / 50.0)).obstacles)
        medium = RadioMedium(MediumConfig(), np.random.default_rng(seed), obstacles)
        ids = list(range(n))
        packets = [Packet(i, BROADCAST, Kind.HEARTBEAT, 0, 1, bytes(payload_bytes))
                   for i in ids]
        medium.update_positions(ids, positions)   # warm-up
        send_and_deliver(medium, packets, -1.0)
        links, traffic, delivered = [], [], []
        for k in range(repeats):
            moved = positions + rng.normal(0.0, 0.05, positions.shape)
            links.append(timed(medium.update_positions, ids, moved)[0])
            wall, count = timed(send_and_deliver, medium, packets, float(k))
            traffic.append(wall)
            delivered.append(count)
        row = {'agents': n, 'obstacles': len(obstacles), 'payload_bytes': payload_bytes,
               'links_s': median(links), 'transmit_deliver_s': median(traffic),
               'step_s': median(np.add(links, traffic)), 'deliveries': median(delivered),
               'mean_degree': median(delivered) / n}
        rows.append(row)
        log(f'  medium {n:5d} agents: links {row["links_s"] * 1e3:.1f} ms, transmit+deliver '
            f'{row["transmit_deliver_s"] * 1e3:.1f} ms ({row["deliveries"]:.0f} deliveries)')
    return rows


def bench_world(sizes: Sequence[int], repeats: int, seconds: float, seed: int) -> list[dict]:
    """scripts/sim_benchmark.py per size, each run in a fresh process (pybullet state)."""
    rows = []
    for n in sizes:
        runs = []
        for k in range(repeats):
            proc = run_child([sys.executable, str(ROOT / 'scripts' / 'sim_benchmark.py'),
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
    if str(ROOT / 'scripts') not in sys.path:
        sys.path.insert(0, str(ROOT / 'scripts'))
    import evaluate

    args = evaluate.parse_args(['--method', 'bubble', '--shape', shape, '--agents',
                                str(agents), '--beacons', str(beacons), '--duration',
                                str(duration_s), '--out', str(tempfile.gettempdir())])
    trials = []
    for k in range(repeats):
        cpu0 = time.process_time()
        wall, record = timed(evaluate.run_trial, args, seed + k)
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


# ---------------------------------------------------------------------------- targets
def at_size(rows: Sequence[dict], n: int) -> dict | None:
    return next((r for r in rows if r.get('agents') == n), None)


def targets(results: dict) -> list[dict]:
    """The issue's targets, each met (True), missed (False) or not measured (None)."""
    out = []

    def add(name: str, value: float | None, op: str, bound: float, unit: str,
            note: str = '') -> None:
        met = None if value is None else (value < bound if op == '<' else value >= bound)
        out.append({'target': name, 'value': value, 'op': op, 'bound': bound, 'unit': unit,
                    'met': met, 'note': note})

    s = results['sections']
    big = at_size(s.get('assignment', []), TARGET_SIZE)
    add(f'assignment, {TARGET_SIZE} agents (all types), per round',
        big and big['assign_all_s'], '<', ROUND_TARGET_S, 's')
    big = at_size(s.get('cost_rows', []), TARGET_SIZE)
    add(f'cost row, {TARGET_SIZE} agents, one agent per round (worst agent, first round '
        'after new goals)', big and big['row_worst_first_s'], '<', ROUND_TARGET_S, 's',
        'each agent computes only its own row')
    add(f'cost rows, {TARGET_SIZE} agents, every agent in one process per round',
        big and big['all_rows_s'], '<', ROUND_TARGET_S, 's',
        'what the headless evaluator pays; not a stated target of each agent')
    world = at_size(s.get('world', []), WORLD_TARGET[0])
    add(f'pybullet world (issue 6), {WORLD_TARGET[0]} robots on rough terrain, real-time '
        'factor', world and world['real_time_factor'], '>=', WORLD_TARGET[1], 'x',
        f'at {world["physics_hz"]:g} Hz physics, state read every step' if world else '')
    ev = s.get('evaluator')
    value = ev['trials_per_min_all_cores'] if ev and ev['agents'] == 50 else None
    add('evaluator, 50-agent thesis scenario, trials per minute (all cores)', value, '>=',
        EVAL_TARGET_PER_MIN, 'trials/min',
        f'trials bounded to {ev["duration_bound_s"]:g} sim-s; a full trial runs until '
        'settled, so it is slower' if ev else '')
    ros = s.get('ros') or []
    for mode, n, rtf in ROS_TARGETS:
        row = next((r for r in ros if r['mode'] == mode and r['agents'] == n), None)
        add(f'ROS, {n} agents {mode}, real-time factor once started',
            row and row.get('steady_real_time_factor'), '>=', rtf, 'x',
            (f'whole run with start-up: {fmt_num(row.get("real_time_factor"))}'
             if row else 'run with --ros'))
    if results['config']['quick']:
        for t in out:
            t.update(met=None, note='--quick: figures not representative')
    return out


# ---------------------------------------------------------------------------- report
def fmt_s(value: float | None) -> str:
    """Seconds with a unit that keeps three significant digits."""
    if value is None:
        return 'n/a'
    if value < 1e-3:
        return f'{value * 1e6:.3g} us'
    if value < 1.0:
        return f'{value * 1e3:.3g} ms'
    return f'{value:.3g} s'


def fmt_num(value: float | None, digits: int = 2) -> str:
    return 'n/a' if value is None else f'{value:.{digits}f}'


def scaling_table(results: dict) -> list[str]:
    s = results['sections']
    sizes = results['config']['sizes']

    def cells(rows: list[dict] | None, fn: Callable[[dict], str]) -> list[str]:
        return [fn(r) if (r := at_size(rows or [], n)) else '-' for n in sizes]

    def dsdv(key: str) -> Callable[[dict], str]:
        return lambda r: ('not converged' if r[key] is None else
                          f'{r[key]:.2f} s ({r[key[:-2] + "_periods"]:.2f} periods)')

    def part(method: str) -> list[str]:
        rows = [r for r in s.get('partition', []) if r['method'] == method]
        return cells(rows, lambda r: fmt_s(r['seconds_median']))

    table = [
        ('DSDV convergence after a link break (simulated time)', 'dsdv',
         cells(s.get('dsdv'), dsdv('link_break_s'))),
        ('DSDV cold start to all shortest routes (simulated time)', 'dsdv',
         cells(s.get('dsdv'), dsdv('cold_start_s'))),
        ('DSDV routing traffic per agent (payload)', 'dsdv',
         cells(s.get('dsdv'), lambda r: f'{r["routing_bytes_per_s_per_agent"]:.0f} B/s')),
        ('Trilateration: localization round of every agent', 'trilateration',
         cells(s.get('trilateration'), lambda r: fmt_s(r['round_s']))),
        ('Partition: bubble packing', 'partition', part('bubble')),
        ('Partition: randomized fractals', 'partition', part('fractal')),
        ('Visibility graph build (one type, shape change)', 'cost_rows',
         cells(s.get('cost_rows'), lambda r: fmt_s(r['graph_build_s']))),
        ('Cost row of one agent (median agent, steady round)', 'cost_rows',
         cells(s.get('cost_rows'), lambda r: fmt_s(r['row_median_s']))),
        ('Cost row of one agent (worst agent, first round after new goals)', 'cost_rows',
         cells(s.get('cost_rows'), lambda r: fmt_s(r['row_worst_first_s']))),
        ('Cost rows of every agent (one process, steady round)', 'cost_rows',
         cells(s.get('cost_rows'), lambda r: fmt_s(r['all_rows_s']))),
        ('Hungarian assignment over every row (all types)', 'assignment',
         cells(s.get('assignment'), lambda r: fmt_s(r['assign_all_s']))),
        ('Hungarian assignment of one type (what one agent solves)', 'assignment',
         cells(s.get('assignment'), lambda r: fmt_s(r['assign_one_type_s']))),
        ('Radio medium: links (range + line of sight)', 'medium',
         cells(s.get('medium'), lambda r: fmt_s(r['links_s']))),
        ('Radio medium: one broadcast per agent sent and delivered', 'medium',
         cells(s.get('medium'), lambda r: fmt_s(r['transmit_deliver_s']))),
    ]
    lines = ['| Algorithm | ' + ' | '.join(f'{n} agents' for n in sizes) + ' |',
             '|---|' + '---|' * len(sizes)]
    lines += [f'| {label} | ' + ' | '.join(values) + ' |'
              for label, section, values in table if section in s]
    return lines


def executor_paragraph(ex: dict) -> list[str]:
    """The executor table and the 'what we chose and why' paragraph, from the numbers."""
    single, events = ex['executors'].get('single'), ex['executors'].get('events')
    lines = ['| Executor | callbacks/s | timer rate achieved [Hz] | CPU cores | '
             'cores per 1000 callbacks/s |', '|---|---|---|---|---|']
    for kind, r in ex['executors'].items():
        lines.append(f'| {kind} | {r["callbacks_per_s"]:.0f} | '
                     f'{r["timer_rate_achieved"]:.1f} | {r["cpu_cores"]:.2f} | '
                     f'{r["cores_per_1000_cb_s"]:.3f} |')
    lines.append('')
    chosen = ex.get('composed_node_default', 'unknown')
    text = (f'**What we chose and why.** `composed_node` spins its agents with '
            f'`agent_node.make_executor()`, which gives a `{chosen}` unless '
            '`SWARM_EXECUTOR=events` is set.')
    if not (single and events):
        return lines + [text]
    ratio = single['cores_per_1000_cb_s'] / max(events['cores_per_1000_cb_s'], 1e-9)
    events_cheaper = ratio > 1
    change = abs(1.0 - 1.0 / ratio) * 100
    text += (f' Measured here, the EventsExecutor needs {change:.0f} % '
             f'{"less" if events_cheaper else "more"} CPU per callback than the '
             f'SingleThreadedExecutor ({events["cores_per_1000_cb_s"]:.3f} vs '
             f'{single["cores_per_1000_cb_s"]:.3f} cores per 1000 callbacks/s).')
    for kind, r in (('SingleThreadedExecutor', single), ('EventsExecutor', events)):
        if r['timer_rate_achieved'] < 0.95 * ex['rate_hz']:
            text += (f' The {kind} fell behind: its timers fired at '
                     f'{r["timer_rate_achieved"]:.1f} of {ex["rate_hz"]:g} Hz with '
                     f'{r["cpu_cores"]:.2f} cores busy.')
    check = ex.get('agents_check') or {}
    ok = {k: v.get('works') for k, v in check.items()}
    if 'single' in check and 'events' in check and None not in ok.values():
        c = check['single']
        text += (f' With the real agents (`scripts/launch_swarm.py --composed`, '
                 f'{c["agents"]} agents, {c["duration_s"]:g} simulated seconds on `/clock`) '
                 'the monitor heard ' + ' and '.join(
                     f'{check[k]["agents_heard"]}/{check[k]["agents"]} agents moving '
                     f'{fmt_num(check[k]["total_displacement"], 0)} m in total under the '
                     f'{name}' for k, name in (('single', 'SingleThreadedExecutor'),
                                               ('events', 'EventsExecutor'))) + '.')
    if chosen == 'SingleThreadedExecutor' and events_cheaper:
        if ok.get('events') is False:
            text += (' So the SingleThreadedExecutor stays: the EventsExecutor is cheaper, '
                     'but the agents do not run under it on sim time (the `make_executor` '
                     'docstring reports the same for rclpy 7.1). Switching is worth it once '
                     'that is understood and fixed; wall-clock runs can opt in with '
                     '`SWARM_EXECUTOR=events`.')
        elif ok.get('events') and ok.get('single'):
            text += (' The agents run under both, so the numbers argue for making the '
                     'EventsExecutor the default of `make_executor`.')
        else:
            text += (' It stays the default because, per the `make_executor` docstring, the '
                     "EventsExecutor's timers did not fire on `/clock` with `use_sim_time` "
                     'in rclpy 7.1 (not re-checked in this run: --executor-check-agents).')
    elif chosen == 'EventsExecutor' and not events_cheaper:
        text += ' On these numbers the SingleThreadedExecutor would be the cheaper default.'
    return lines + [text]


def write_markdown(path: pathlib.Path, results: dict) -> None:
    m, c, s = results['machine'], results['config'], results['sections']
    dirty = ' (with uncommitted changes in the working tree)' if m['git_dirty'] else ''
    lines = ['# Benchmarks', '',
             'Generated by `scripts/env.sh python benchmarks/run_all.py` '
             f'({shlex.join(c["argv"]) or "default arguments"}); do not edit by hand. '
             'Raw figures: `benchmarks.json` next to this file.', '',
             f'Machine: {m["cpu_count"]} cores, Python {m["python"]}, {m["platform"]}; '
             f'load average {m["loadavg_start"][0]:.2f} at the start and '
             f'{m["loadavg_end"][0]:.2f} at the end; {m["date"]}; commit '
             f'`{m["git_commit"][:12]}`{dirty}.'
             + (f' {c["note"]}' if c['note'] else ''), '']
    # Each section's figures come from the last run that measured it (the JSON keeps
    # every --update run; the report names only the ones its figures come from).
    source = {name: u for u in results.get('updates', []) for name in u['sections']}
    if source:
        lines += ['Sections measured by a separate `--update` run (the others by the run '
                  'above):', '']
    for u in results.get('updates', []):
        names = [name for name in u['sections'] if source[name] is u]
        if not names:
            continue
        u_dirty = ' with uncommitted changes' if u['git_dirty'] else ''
        argv = [a for i, a in enumerate(u['argv'])
                if a != '--note' and (i == 0 or u['argv'][i - 1] != '--note')]
        lines += [f'{", ".join(names)}: measured on {u["date"]} at commit '
                  f'`{u["git_commit"][:12]}`{u_dirty} (load average '
                  f'{u["loadavg_start"][0]:.2f} at the start and {u["loadavg_end"][0]:.2f} '
                  f'at the end) by `run_all.py {shlex.join(argv)}`.'
                  + (f' {u["note"]}' if u['note'] else ''), '']
    lines += [f'Times are medians of {c["repeats"]} runs (DSDV: {c["dsdv_repeats"]} random '
              'graph(s) per size); sizes scale the thesis scenario (50 agents in '
              '100 m x 100 m, 314 m^2 formation, 20:20:10 types) at constant density.', '',
              '## Scaling per algorithm', '']
    lines += scaling_table(results)
    if s.get('world'):
        lines += ['', '## pybullet world (scripts/sim_benchmark.py)', '',
                  '| Robots | Physics rate | Real-time factor | CPU real-time factor | '
                  'Wall per step | Physics share | Max tilt | Min ground clearance |',
                  '|---|---|---|---|---|---|---|---|']
        for r in s['world']:
            lines.append(f'| {r["robots"]} | {r["physics_hz"]:g} Hz | '
                         f'{fmt_num(r["real_time_factor"], 1)} | '
                         f'{fmt_num(r["cpu_real_time_factor"], 1)} | '
                         f'{fmt_s(r["ms_per_step"] / 1e3)} | '
                         f'{100 * r["physics_share"]:.0f} % | {r["max_tilt_deg"]:.1f} deg | '
                         f'{100 * r["min_ground_clearance_m"]:.1f} cm |')
        lines += ['', f'Each run: {s["world"][0]["seconds"]:g} simulated seconds on rough '
                  'terrain in the +/-50 m workspace (DIRECT mode, the three types 20:20:10), '
                  'every robot driven towards a new random velocity up to 0.5 m/s every 2 s '
                  'by a 50 Hz controller, the state (poses and velocities) read after every '
                  "physics step, the worst case. Physics share: the time inside Bullet's "
                  'step; the rest is the Python side (forces, state reads).']
    if 'evaluator' in s:
        ev = s['evaluator']
        lines += ['', '## Headless evaluator', '',
                  f'Whole trials of scripts/evaluate.py (`run_trial`): {ev["agents"]} agents, '
                  f'{ev["beacons"]} beacons, {ev["shape"]}, {ev["method"]}, bounded to '
                  f'{ev["duration_bound_s"]:g} simulated seconds (--eval-duration; '
                  f'{ev["settled_share"] * 100:.0f} % of the trials settled within it).', '',
                  '| Wall per trial | CPU per trial | Sim-s per trial | Sim-s per wall-s | '
                  'Trials/min (one process) | Trials/min (all cores, from CPU time) |',
                  '|---|---|---|---|---|---|',
                  f'| {ev["wall_per_trial_s"]:.1f} s | {ev["cpu_per_trial_s"]:.1f} s | '
                  f'{ev["sim_s_per_trial"]:.0f} | {ev["sim_s_per_wall_s"]:.2f} | '
                  f'{ev["trials_per_min_one_process"]:.2f} | '
                  f'{ev["trials_per_min_all_cores"]:.2f} ({ev["cores"]} cores) |']
    if 'executor' in s:
        ex = s['executor']
        lines += ['', '## Executor', '',
                  f'benchmarks/bench_executor.py: {ex["nodes"]} nodes in one process, a '
                  f'{ex["rate_hz"]:g} Hz wall-clock timer publishing and one subscription '
                  f'each, {ex["seconds"]:g} s per executor.', '']
        lines += executor_paragraph(ex)
    lines += ['', '## ROS 2 swarm (scripts/launch_swarm.py)', '']
    if s.get('ros'):
        lines += ['| Agents | Mode | Real-time factor once started | Start-up (wall) | '
                  'Real-time factor, whole run | CPU cores | Peak memory (PSS) | Outcome |',
                  '|---|---|---|---|---|---|---|---|']
        for r in s['ros']:
            startup = r.get('startup_wall_seconds')
            lines.append(f'| {r["agents"]} | {r["mode"]} | '
                         f'{fmt_num(r.get("steady_real_time_factor"))} | '
                         f'{fmt_s(startup) if startup is not None else "n/a"} | '
                         f'{fmt_num(r.get("real_time_factor"))}'
                         f' | {fmt_num(r.get("cpu_cores_used"))} | '
                         f'{fmt_num(r.get("peak_pss_mb") or r.get("peak_rss_mb"), 0)} MB | '
                         f'{r.get("outcome") or r.get("error", "")} |')
        lines.append('')
        lines.append(f'Each run: {c["ros_duration"]:g} simulated seconds of the thesis '
                     'scenario (15 % beacons, circle_314, bubble). Start-up: wall seconds '
                     'until the launcher had heard every agent (processes, DDS discovery, '
                     'first commands; the world waits for them). Real-time factor once '
                     'started: simulated over wall seconds from then to the end. Peak '
                     'memory: proportional set size of every process of the run (pages '
                     'shared by k processes counted 1/k in each), sampled every 10 s.')
    else:
        lines += ['Not run (slow). Run it with '
                  '`scripts/env.sh python benchmarks/run_all.py --ros --ros-sizes 20,50,100 '
                  '--ros-duration 30` (per-process and composed at each size, a few minutes '
                  'each on 2 cores).']
    lines += ['', '## Targets (issues 6 and 9)', '',
              '| Target | Measured | Wanted | Result | Note |', '|---|---|---|---|---|']
    for t in results['targets']:
        if t['unit'] == 's':
            value = fmt_s(t['value'])
        else:
            value = fmt_num(t['value'])
        wanted = f'{t["op"]} {t["bound"]:g} {t["unit"]}'
        verdict = {True: 'met', False: 'missed', None: 'not measured'}[t['met']]
        lines.append(f'| {t["target"]} | {value} | {wanted} | {verdict} | {t["note"]} |')
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')


def jsonable(value):
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def git(*args: str) -> str:
    try:
        return subprocess.run(['git', *args], cwd=str(ROOT), capture_output=True, text=True,
                              timeout=30, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ''


# ---------------------------------------------------------------------------- main
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--sizes', default='50,200,1000', help='swarm sizes, e.g. 50,200,1000')
    p.add_argument('--repeats', type=int, default=3, help='runs per figure (median)')
    p.add_argument('--dsdv-repeats', type=int, default=1,
                   help='random graphs per size for DSDV (simulated-time figures)')
    p.add_argument('--dsdv-limit', type=float, default=120.0,
                   help='give up on DSDV convergence after this many simulated seconds')
    p.add_argument('--world-sizes', default=None,
                   help='robots of the pybullet world section (default 50,200, --quick 10)')
    p.add_argument('--world-seconds', type=float, default=None,
                   help='simulated seconds per world run (default 20, --quick 1)')
    p.add_argument('--eval-duration', type=float, default=None,
                   help='simulated seconds per evaluator trial (default 60, --quick 3)')
    p.add_argument('--eval-agents', type=int, default=50)
    p.add_argument('--eval-beacons', type=int, default=8)
    p.add_argument('--executor-nodes', type=int, default=None,
                   help='nodes of bench_executor.py (default 50, --quick 5)')
    p.add_argument('--executor-seconds', type=float, default=None,
                   help='seconds per executor (default 5, --quick 1)')
    p.add_argument('--executor-check-agents', type=int, default=10,
                   help='composed agents run on sim time under each executor to check that '
                        'they work (0: skip; skipped with --quick)')
    p.add_argument('--only', default='', help=f'comma list of sections out of {SECTIONS}')
    p.add_argument('--ros', action='store_true', help='also run the ROS swarm section (slow)')
    p.add_argument('--ros-sizes', default='20,50,100')
    p.add_argument('--ros-duration', type=float, default=30.0,
                   help='simulated seconds per ROS run')
    p.add_argument('--ros-timeout', type=float, default=900.0,
                   help='wall seconds before a ROS run is stopped')
    p.add_argument('--quick', action='store_true',
                   help='tiny figures to check that the suite runs (tests)')
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--note', default='', help='free text for the report, e.g. machine load')
    p.add_argument('--out', default=str(ROOT / 'docs'),
                   help='directory for benchmarks.md and benchmarks.json')
    p.add_argument('--update', action='store_true',
                   help='keep the sections of the benchmarks.json in --out that this run does '
                        'not measure, e.g. --only executor --update or --only ros --update')
    p.add_argument('--render', action='store_true',
                   help='measure nothing: rewrite benchmarks.md from the benchmarks.json in '
                        '--out (after a change of the report format)')
    args = p.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    if args.eval_duration is None:
        args.eval_duration = 3.0 if args.quick else 60.0
    if args.world_sizes is None:
        args.world_sizes = '10' if args.quick else '50,200'
    if args.world_seconds is None:
        args.world_seconds = 1.0 if args.quick else 20.0
    if args.executor_nodes is None:
        args.executor_nodes = 5 if args.quick else 50
    if args.executor_seconds is None:
        args.executor_seconds = 1.0 if args.quick else 5.0
    return args


def sizes_arg(text: str, name: str, least: int) -> list[int]:
    try:
        sizes = [int(v) for v in text.split(',')]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < least:
        raise BenchError(f'{name} must be integers >= {least} separated by commas, like '
                         f'50,200,1000 (got {text!r})')
    return sizes


def validate(args: argparse.Namespace) -> tuple[list[int], list[int], list[str]]:
    sizes = sizes_arg(args.sizes, '--sizes', 10)
    ros_sizes = sizes_arg(args.ros_sizes, '--ros-sizes', 3)
    for name in ('repeats', 'dsdv_repeats', 'executor_nodes', 'eval_agents'):
        if getattr(args, name) < 1:
            raise BenchError(f'--{name.replace("_", "-")} must be at least 1')
    args.world_size_list = sizes_arg(args.world_sizes, '--world-sizes', 1)
    for name in ('eval_duration', 'world_seconds', 'executor_seconds', 'ros_duration',
                 'dsdv_limit', 'ros_timeout'):
        if not getattr(args, name) > 0:
            raise BenchError(f'--{name.replace("_", "-")} must be positive')
    if not 3 <= args.eval_beacons <= args.eval_agents:
        raise BenchError(f'--eval-beacons must be between 3 and --eval-agents '
                         f'({args.eval_agents})')
    only = [s for s in args.only.split(',') if s] or list(SECTIONS)
    unknown = sorted(set(only) - set(SECTIONS) - {'ros'})
    if unknown:
        raise BenchError(f'--only: unknown section(s) {unknown}; choose from '
                         f'{(*SECTIONS, "ros")}')
    if 'ros' in only:
        args.ros = True
    return sizes, ros_sizes, only


def merge_previous(results: dict, out: pathlib.Path, measured: list[str]) -> dict:
    """--update: the existing report with this run's sections replaced and the run logged."""
    source = out / 'benchmarks.json'
    try:
        old = json.loads(source.read_text(encoding='utf-8'))
        old_sections, old_config = old['sections'], old['config']
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise BenchError(f'--update needs a readable {source} ({type(exc).__name__}); run '
                         'the suite without --update first') from None
    sized = {'dsdv', 'trilateration', 'partition', 'cost_rows', 'assignment', 'medium'}
    if sized & set(measured) and results['config']['sizes'] != old_config['sizes']:
        raise BenchError(f'--update: --sizes {results["config"]["sizes"]} differs from the '
                         f'existing report\'s {old_config["sizes"]}; use the same sizes')
    merged = dict(old)
    merged['sections'] = {**old_sections, **results['sections']}
    merged['section_wall_s'] = {**old.get('section_wall_s', {}), **results['section_wall_s']}
    merged['config'] = dict(old_config)
    if 'ros' in measured:
        merged['config'].update(ros=True, ros_sizes=results['config']['ros_sizes'],
                                ros_duration=results['config']['ros_duration'])
    m = results['machine']
    merged['updates'] = [*old.get('updates', []), {
        'sections': measured, 'argv': results['config']['argv'], 'date': m['date'],
        'git_commit': m['git_commit'], 'git_dirty': m['git_dirty'],
        'loadavg_start': m['loadavg_start'], 'loadavg_end': m['loadavg_end'],
        'repeats': results['config']['repeats'], 'note': results['config']['note']}]
    return merged


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.render:
        source = pathlib.Path(args.out) / 'benchmarks.json'
        try:
            results = json.loads(source.read_text(encoding='utf-8'))
            write_markdown(source.with_suffix('.md'), results)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            print(f'run_all: error: cannot render {source} ({type(exc).__name__}: {exc}); '
                  'run the suite first', file=sys.stderr)
            return 2
        log(f'wrote {source.with_suffix(".md")} from {source}')
        return 0
    try:
        sizes, ros_sizes, only = validate(args)
    except BenchError as exc:
        print(f'run_all: error: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    commit = git('rev-parse', 'HEAD') or 'unknown'
    results: dict = {
        'machine': {'cpu_count': os.cpu_count(), 'python': platform.python_version(),
                    'platform': platform.platform(), 'processor': platform.processor(),
                    'date': datetime.datetime.now(datetime.UTC).isoformat(
                        timespec='seconds'),
                    'git_commit': commit, 'git_dirty': bool(git('status', '--porcelain')),
                    'loadavg_start': list(os.getloadavg())},
        'config': {'sizes': sizes, 'repeats': args.repeats, 'dsdv_repeats': args.dsdv_repeats,
                   'eval_duration': args.eval_duration, 'quick': args.quick,
                   'ros': args.ros, 'ros_sizes': ros_sizes if args.ros else [],
                   'ros_duration': args.ros_duration, 'seed': args.seed, 'note': args.note,
                   'argv': args.argv},
        'sections': {}, 'section_wall_s': {}}
    s = results['sections']
    wall0 = time.perf_counter()
    plan: list[tuple[str, Callable[[], None]]] = [
        ('dsdv', lambda: s.__setitem__('dsdv', bench_dsdv_section(
            sizes, args.dsdv_repeats, args.dsdv_limit))),
        ('trilateration', lambda: s.__setitem__('trilateration', bench_trilateration(
            sizes, args.repeats, args.seed))),
        ('partition', lambda: s.__setitem__('partition', bench_partition_section(
            sizes, args.repeats))),
        ('cost_rows', lambda: s.update(zip(('cost_rows', 'assignment'), bench_costs(
            sizes, args.repeats, args.seed)))),
        ('medium', lambda: s.__setitem__('medium', bench_medium(
            sizes, args.repeats, args.seed))),
        ('world', lambda: s.__setitem__('world', bench_world(
            args.world_size_list, args.repeats, args.world_seconds, args.seed))),
        ('evaluator', lambda: s.__setitem__('evaluator', bench_evaluator(
            args.eval_duration, args.repeats, args.eval_agents, args.eval_beacons,
            'circle_314', args.seed))),
        ('executor', lambda: s.__setitem__('executor', bench_executor_section(
            args.executor_nodes, 50.0, args.executor_seconds, args.repeats,
            0 if args.quick else args.executor_check_agents))),
    ]
    if args.update and not (out / 'benchmarks.json').exists():
        print(f'run_all: error: --update needs {out / "benchmarks.json"}; run the suite '
              'without --update first', file=sys.stderr)
        return 2
    for name, run in plan:
        wanted = name in only or (name == 'cost_rows' and 'assignment' in only)
        if not wanted:
            continue
        log(f'{name} ...')
        t0 = time.perf_counter()
        run()
        results['section_wall_s'][name] = time.perf_counter() - t0
    if args.ros:
        log('ros ...')
        t0 = time.perf_counter()
        work = pathlib.Path(tempfile.mkdtemp(prefix='run_all_ros_'))
        s['ros'] = bench_ros(ros_sizes, args.ros_duration, args.ros_timeout, work)
        if any('error' in row for row in s['ros']):
            log(f'  a ROS run failed: its launcher.log and node logs are kept in {work}')
        else:
            shutil.rmtree(work, ignore_errors=True)
        results['section_wall_s']['ros'] = time.perf_counter() - t0
    results['machine']['loadavg_end'] = list(os.getloadavg())
    results['total_wall_s'] = time.perf_counter() - wall0
    if args.update:
        measured = [*results['section_wall_s']]
        if 'cost_rows' in measured:
            measured.append('assignment')
        try:
            results = merge_previous(results, out, measured)
        except BenchError as exc:
            print(f'run_all: error: {exc}', file=sys.stderr)
            return 2
    results['targets'] = targets(results)
    results = jsonable(results)
    (out / 'benchmarks.json').write_text(json.dumps(results, indent=1) + '\n',
                                         encoding='utf-8')
    write_markdown(out / 'benchmarks.md', results)
    log(f'\nTargets ({time.perf_counter() - wall0:.0f} s for this run):')
    for t in results['targets']:
        verdict = {True: 'met', False: 'MISSED', None: 'not measured'}[t['met']]
        value = 'n/a' if t['value'] is None else f'{t["value"]:.3g}'
        log(f'  {verdict:12s} {t["target"]}: {value} {t["unit"]} (wanted {t["op"]} '
            f'{t["bound"]:g})')
    log(f'wrote {out / "benchmarks.md"} and {out / "benchmarks.json"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
