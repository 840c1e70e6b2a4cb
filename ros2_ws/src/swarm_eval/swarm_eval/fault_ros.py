"""The fault study through the full ROS system (sim_node, mission_node, composed agents):
one ``scripts/launch_swarm.py`` run per (case, seed), faults by its --remove and
--set-sim (a rogue transmitter too: sim_node's ``rogue``), each run's row read back from
its metrics.json, record.npz and logs (the agents' status lines give the frames they
rejected, by kind)."""

from __future__ import annotations

import argparse
import ast
import json
import math
import pathlib
import re
import sys
from typing import Any

import numpy as np

from swarm_bringup import scenario as launcher
from swarm_common.robot_types import RobotTypeError
from swarm_common.shapes import ShapeError
from swarm_eval.fault_cases import (
    fault_cases,
    fault_plan,
    override,
    ROS_CASES,
    select_cases,
)
from swarm_eval.fault_probes import (
    count_loops,
    coverage_columns,
    fewest_beacons_heard,
    judge,
    link_components,
    SAMPLE_EVERY,
)
from swarm_eval.fault_report import markdown_table, plot, summarise, write_json
from swarm_eval.paths import repo_root
from swarm_mission.partition import PartitionError
from swarm_sim.headless import ScenarioError
from swarm_sim.medium import apply_setting, MediumConfig, RadioMedium

ROOT = repo_root()
LAUNCH = ROOT / 'scripts' / 'launch_swarm.py'
ROUTE_FRESH_S = 5.0     # a route table older than this (sim s) is of a dead agent
NO_ROUTE = 255          # swarm_msgs/RouteEntry.INFINITE_HOPS, also "no entry"
# An agent's status line (AgentBrain.status_line, logged every status_log_period_s).
_STATUS = re.compile(r'agent_(\d+)\]: .*; rejected frames (\{[^}]*\})')


def ros_config(args: argparse.Namespace) -> dict[str, Any]:
    """Defaults of the ROS study (the e2e test's 12-agent square), overridden by args."""
    base = {'agents': 12, 'beacons': 4, 'seeds': 1, 'half_size': 15.0, 'fault_time': 80.0,
            'duration': 240.0, 'observe': 60.0, 'ranges': (2.0,), 'wall_speed': 1.0,
            'shape': str(ROOT / 'tests' / 'data' / 'square_8m.json'), 'settle_hold': 3.0,
            'timeout': 1200.0}
    override(base, args, ('agents', 'beacons', 'seeds', 'half_size', 'fault_time',
                           'duration', 'observe', 'shape'))
    base.update(method=args.method, fault_window=args.fault_window, seed=args.seed,
                ros=True, composed=True)
    return base


def ros_launch_argv(case: dict, config: dict, seed: int, run_dir: pathlib.Path
                    ) -> tuple[list[str], dict[str, Any]]:
    """launch_swarm.py arguments of a (case, seed) run and the case's fault plan."""
    argv = ['--agents', str(config['agents']), '--beacons', str(config['beacons']),
            '--method', config['method'], '--shape', str(config['shape']),
            '--half-size', f'{config["half_size"]:g}', '--duration', f'{config["duration"]:g}',
            '--settle-hold', f'{config["settle_hold"]:g}', '--composed', '--seed', str(seed),
            '--no-record', '--out', str(run_dir)]   # a study's runs record no bag
    try:
        _, _, _, fleet = launcher.validate(launcher.parse_args(argv))
    except launcher.LaunchError as exc:
        raise ScenarioError(f'launch_swarm refuses the scenario: {exc}') from None
    robots = sorted(fleet, key=lambda r: r.id)
    plan = fault_plan(case, config, seed, [r.id for r in robots],
                      [r.id for r in robots if r.is_beacon], config['half_size'])
    for t, victims in plan['removals']:
        argv += ['--remove', f'{t:.2f}:' + ','.join(str(v) for v in victims)]
    for t, name, value in plan['settings']:
        argv += ['--set-sim', f'{t:g}:{name}={value:g}']
    if case['kind'] != 'loss':
        until = min(config['duration'], plan['last'] + config['observe'])
        argv += ['--min-duration', f'{until:g}']
    return argv, plan


def run_ros_case(case: dict, config: dict, seed: int, out: pathlib.Path) -> dict[str, Any]:
    """One launch_swarm run of the case (its output in out/CASE_sSEED/), and its row."""
    import shutil
    import signal
    import subprocess
    import time

    run_dir = out / f'{case["name"]}_s{seed}'
    if run_dir.exists():
        shutil.rmtree(run_dir)
    argv, plan = ros_launch_argv(case, config, seed, run_dir)
    run_dir.mkdir(parents=True)
    (run_dir / 'command.txt').write_text(' '.join(['scripts/launch_swarm.py', *argv]) + '\n',
                                         encoding='utf-8')
    wall0 = time.monotonic()
    with open(run_dir / 'launcher.log', 'w', encoding='utf-8') as log:
        proc = subprocess.Popen([sys.executable, str(LAUNCH), *argv], stdout=log,
                                stderr=subprocess.STDOUT, cwd=str(ROOT))
        try:
            returncode = proc.wait(timeout=config['timeout'])
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)   # the launcher stops its children itself
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            returncode = None
    return ros_row(case, config, seed, run_dir, plan, returncode, time.monotonic() - wall0)


def _crashed_nodes(run_dir: pathlib.Path, metrics: dict) -> tuple[list[str], list[str]]:
    """Nodes that died during the run (the launcher's crash outcome), and node logs with a
    traceback (a crash, or an exception while the launcher stopped them at the end)."""
    crashed = []
    outcome = str(metrics.get('outcome', ''))
    if outcome.startswith('crash of '):
        crashed.append(outcome[len('crash of '):])
    tracebacks = [log.stem for log in sorted((run_dir / 'logs').glob('*.log'))
                  if 'Traceback (most recent call last)' in log.read_text(
                      encoding='utf-8', errors='replace')]
    return crashed, tracebacks


def rejected_from_logs(run_dir: pathlib.Path) -> dict[str, int] | None:
    """Frames the agents rejected, by kind: the sum over agents of the counts in each
    one's last status line (its counts are totals since it started); None without any."""
    last: dict[int, dict[str, int]] = {}
    for log in sorted((run_dir / 'logs').glob('*.log')):
        for line in log.read_text(encoding='utf-8', errors='replace').splitlines():
            match = _STATUS.search(line)
            if match:
                try:
                    last[int(match[1])] = dict(ast.literal_eval(match[2]))
                except (ValueError, SyntaxError):
                    continue
    if not last:
        return None
    total: dict[str, int] = {}
    for counts in last.values():
        for kind, n in counts.items():
            total[kind] = total.get(kind, 0) + int(n)
    return dict(sorted(total.items()))


def route_columns(data, record, ids: list[int], first: float) -> dict[str, Any]:
    """DSDV health from the launcher's route samples: hops, loops, stale routes."""
    times = np.asarray(data['route_times'], dtype=float)
    max_hops, vs_size, loops, stale = 0, -math.inf, 0, 0
    for s, t in enumerate(times):
        k = min(int(np.searchsorted(record.times, t)), len(record.times) - 1)
        alive = record.alive[k]
        age = t - data['route_stamp'][s]
        fresh = alive & np.isfinite(age) & (age <= ROUTE_FRESH_S)
        hops = data['route_hops'][s]
        tables = {}
        for i in np.flatnonzero(fresh):
            finite = np.flatnonzero(hops[i] < NO_ROUTE)
            tables[ids[i]] = {ids[j]: int(data['route_next'][s][i, j]) for j in finite}
            if len(finite):
                max_hops = max(max_hops, int(hops[i, finite].max()))
                vs_size = max(vs_size, int(hops[i, finite].max()) - (int(alive.sum()) - 1))
        loops += count_loops(tables)
        if s == len(times) - 1:
            dead = ~record.alive[-1]
            stale = int(sum(np.sum((hops[i] < NO_ROUTE) & dead) for i in np.flatnonzero(fresh)))
    return {'max_hops_seen': max_hops, 'count_to_infinity': bool(vs_size > 0),
            'routing_loops': loops, 'stale_routes_to_dead': stale,
            'route_samples': len(times)}


def link_columns(record, ids: list[int], is_beacon: np.ndarray, settings: list, config: dict,
                 shape, first: float) -> dict[str, Any]:
    """Replay the medium's link graph on the recorded truth with the settings applied."""
    medium = RadioMedium(MediumConfig(), np.random.default_rng(0), list(shape.obstacles))
    pending = sorted(settings)
    components_after, final = 0, 0
    frames = list(range(0, len(record.times), SAMPLE_EVERY))
    if frames[-1] != len(record.times) - 1:
        frames.append(len(record.times) - 1)
    for k in frames:
        t = float(record.times[k])
        while pending and pending[0][0] <= t:
            when, name, value = pending.pop(0)
            if name != 'rogue':   # the world's, not the medium's
                apply_setting(medium, name, value, when, config['half_size'])
        medium.move_wall(t)
        living = np.flatnonzero(record.alive[k])
        medium.update_positions([ids[i] for i in living], record.positions[k][living])
        final = link_components(medium, {ids[i] for i in living})
        if t >= first:
            components_after = max(components_after, final)
    return {'max_components_after_fault': components_after, 'final_components': final,
            'min_beacons_heard': fewest_beacons_heard(medium, ids, record.alive[-1],
                                                      is_beacon)}


def ros_row(case: dict, config: dict, seed: int, run_dir: pathlib.Path, plan: dict,
            returncode: int | None, wall_seconds: float) -> dict[str, Any]:
    """The study's row of one ROS run, from its metrics.json, record.npz and logs."""
    from types import SimpleNamespace

    from swarm_common.fleet import load_fleet
    from swarm_common.shapes import load_shape

    row: dict[str, Any] = {'case': case['name'], 'kind': case['kind'],
                           'value': case['value'], 'seed': seed, 'ros': True,
                           'launcher_exit': returncode, 'wall_seconds': wall_seconds,
                           'run_dir': str(run_dir)}
    try:
        metrics = json.loads((run_dir / 'metrics.json').read_text())['trials'][0]
        data = np.load(run_dir / 'record.npz')
    except (OSError, ValueError, KeyError, IndexError) as exc:
        row.update(error=f'no results: {exc}', crashed=['launcher'], passed=False,
                   target_applies=False, settled=False)
        return row
    row['crashed'], row['tracebacks'] = _crashed_nodes(run_dir, metrics)
    if returncode is None:
        row['crashed'].append('timeout')
    ids = [int(a) for a in data['agent_ids']]
    fleet = {r.id: r for r in load_fleet(run_dir / 'fleet.yaml')}
    types = np.array([fleet[a].type for a in ids])
    is_beacon = np.array([fleet[a].is_beacon for a in ids], dtype=bool)
    goals = [SimpleNamespace(id=int(i), type=int(t), x=float(xy[0]), y=float(xy[1]))
             for i, t, xy in zip(data['goal_id'], data['goal_type'], data['goal_xy'])]
    record = SimpleNamespace(
        times=np.asarray(data['times'], dtype=float),
        positions=np.nan_to_num(np.asarray(data['positions'], dtype=float), nan=0.0),
        velocities=np.asarray(data['velocities'], dtype=float),
        alive=np.asarray(data['alive'], dtype=bool), modes=np.asarray(data['modes']),
        digests=np.asarray(data['digests']), goal_ids=np.asarray(data['goal_ids']),
        types=types, goals=goals)
    if len(record.times) < 2 or 'fraction_inside' not in metrics:
        row.update(error=metrics.get('error', 'run too short'), passed=False,
                   target_applies=False, settled=False)
        return row
    # Settings as the sim applied them (sent when the sim time passed the planned time).
    applied = [(float(e.get('sent_at', e['time'])), e['name'], float(e['value']))
               for e in metrics.get('sim_settings', []) if e.get('ok')]
    shape = load_shape(config['shape'])
    separation = ((np.asarray(data['separation_times'], dtype=float),
                   np.asarray(data['separation_min'], dtype=float))
                  if 'separation_times' in data else None)
    row.update(coverage_columns(record, metrics, plan['first'], plan['last'], separation))
    row.update(route_columns(data, record, ids, plan['first']))
    row.update(link_columns(record, ids, is_beacon, applied, config, shape, plan['first']))
    medium_file = run_dir / 'medium.json'
    row.update({
        'fraction_inside': metrics['fraction_inside'],
        'epsilon_t': metrics.get('epsilon_t'), 'epsilon_g': metrics.get('epsilon_g'),
        'assignment_agreement': metrics.get('assignment_agreement'),
        'duplicate_goal_claims_final': metrics.get('duplicate_goal_claims_final'),
        'duplicate_goal_claims_peak': metrics.get('duplicate_goal_claims_peak'),
        'min_separation_ratio': metrics.get('min_separation_ratio'),
        'contacts': metrics.get('contacts'),
        'beacons_alive': int((is_beacon & record.alive[-1]).sum()),
        'final_modes_normal': metrics.get('final_modes_normal'),
        'rms_localization_error': metrics.get('rms_localization_error'),
        'outcome': metrics.get('outcome'), 'sim_settings': metrics.get('sim_settings', []),
        'settings_failed': [e for e in metrics.get('sim_settings', []) if not e.get('ok')],
        'removals': plan['removals'],
        'medium': json.loads(medium_file.read_text()) if medium_file.exists() else None,
        'real_time_factor': metrics.get('real_time_factor'),
        'frames_rejected': rejected_from_logs(run_dir),
        'duration': metrics.get('duration'),
    })
    return judge(row)


def run_ros_study(args: argparse.Namespace, argv: list[str] | None) -> int:
    """--ros: the cases through launch_swarm, one run at a time; faults_ros.*."""
    import time

    config = ros_config(args)
    cases = select_cases(fault_cases(config['ranges']), args.cases, set(ROS_CASES))
    if cases is None:
        return 2
    headless_only = [c['name'] for c in cases if c['kind'] == 'restart']
    if headless_only:
        print(f'fault_study.py: {", ".join(headless_only)} run headless only (through ROS, '
              'tests/e2e/test_restarts.py kills and respawns agent processes); drop --ros',
              file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    try:
        if config['seeds'] < 1:
            raise ScenarioError('--seeds must be at least 1')
        if config['fault_time'] >= config['duration']:
            raise ScenarioError('--fault-time must be before the end of --duration')
        ros_launch_argv(cases[0], config, config['seed'], out / 'check')
    except (ShapeError, ScenarioError, RobotTypeError, PartitionError) as exc:
        print(f'fault_study.py: {exc}', file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    seeds = [config['seed'] + k for k in range(config['seeds'])]
    rows: list[dict] = []
    wall0 = time.monotonic()
    for case in cases:
        for seed in seeds:
            row = run_ros_case(case, config, seed, out)
            rows.append(row)
            print(f'fault study (ROS): {case["name"]} seed {seed}: '
                  f'{row.get("outcome", row.get("error"))}, passed {row["passed"]}, '
                  f'{row["wall_seconds"]:.0f} s wall', flush=True)
    summary = summarise(rows, cases)
    payload = {'config': config, 'wall_seconds': time.monotonic() - wall0,
               'command': ' '.join(['scripts/fault_study.py', *(
                   argv if argv is not None else sys.argv[1:])]),
               'cases': summary, 'trials': rows}
    write_json(out / 'faults_ros.json', payload)
    (out / 'faults_ros.md').write_text(markdown_table(summary, crashes=True),
                                       encoding='utf-8')
    plot(out / 'faults_ros.png', summary, title='Fault study through ROS')
    print(markdown_table(summary, crashes=True))
    print(f'fault study (ROS): {len(rows)} runs, {payload["wall_seconds"] / 60:.1f} min '
          f'-> {out}')
    return 0

