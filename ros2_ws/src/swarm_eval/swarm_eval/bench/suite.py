"""The benchmark suite in one command: writes docs/benchmarks.md and docs/benchmarks.json.

Every figure comes from the package code (no algorithm is re-implemented here); timings
are medians of --repeats runs, per swarm size of --sizes:

- dsdv:          convergence of the real DsdvRouters after a link break and from a cold
                 start, in simulated seconds (``swarm_eval.bench.dsdv.bench``; one
                 random geometric graph per repeat, --dsdv-repeats, since the figure is
                 deterministic for a graph and a 1000-agent run takes minutes);
- trilateration: one localization round of the swarm (``Localizer.localize`` of every
                 agent with four beacons in radio range);
- partition:     bubble packing and randomized fractals of the thesis circle scaled to
                 the swarm (``swarm_eval.bench.partition.bench``);
- cost_rows:     visibility graph + Dijkstra (``VisibilityGraph.cost_row``) in the thesis
                 workspace with its four obstacles scaled to the swarm: one agent's row
                 (median agent in a steady round; worst agent in the first round after new
                 goals, fresh graph) and every agent's row (what one process running the
                 whole swarm pays per round);
- assignment:    the Hungarian consensus ``assign`` over every agent's row (all types);
- medium:        one step of the radio medium (``RadioMedium.update_positions``: links
                 with line of sight; then one 24-byte broadcast per agent transmitted and
                 delivered);
- world:         the bare pybullet world of swarm_sim (``swarm_eval.sim_benchmark`` in a
                 child process: --world-sizes robots of the three types on rough terrain
                 in the +/-50 m workspace, DIRECT mode, its default physics rate, the
                 state read after every step): real-time factor (issue 6's target: 20x
                 with 50 robots);
- evaluator:     whole headless trials of the thesis scenario (``swarm_eval.scenario``
                 ``run_trial``: 50 agents, 8 beacons, circle_314, bubble) bounded to
                 --eval-duration simulated seconds: wall and CPU seconds per trial, sim
                 seconds per wall second, trials per minute;
- throughput:    issue 23's command (``scripts/evaluate.py ... --agents 50 --trials 20
                 --workers 2``, every trial to its end, start-up included: trials per
                 minute) and --large-agents headless for --large-duration simulated
                 seconds (real-time factor; ``swarm_eval.bench.throughput``);
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
from collections.abc import Callable
import datetime
import json
import os
import pathlib
import platform
import shutil
import sys
import tempfile
import time

from swarm_eval.bench.common import BenchError, git, ISSUE23, log, ROOT, SECTIONS
from swarm_eval.bench.processes import (
    bench_evaluator,
    bench_executor_section,
    bench_ros,
    bench_world,
)
from swarm_eval.bench.report import targets, write_markdown
from swarm_eval.bench.sections import (
    bench_costs,
    bench_dsdv_section,
    bench_medium,
    bench_partition_section,
    bench_trilateration,
)
from swarm_eval.bench.throughput import bench_throughput
from swarm_sim.report import jsonable


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
    p.add_argument('--issue-trials', type=int, default=None,
                   help="trials of issue 23's command (default 20, --quick 2)")
    p.add_argument('--issue-workers', type=int, default=None,
                   help="workers of issue 23's command (default 2, --quick 1)")
    p.add_argument('--large-agents', type=int, default=None,
                   help='agents of the large headless swarm (default 200, --quick 10)')
    p.add_argument('--large-duration', type=float, default=None,
                   help='simulated seconds of the large swarm (default 30, --quick 3)')
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
    for name, full, tiny in (('issue_trials', ISSUE23['trials'], 2),
                             ('issue_workers', ISSUE23['workers'], 1),
                             ('large_agents', ISSUE23['large_agents'], 10),
                             ('large_duration', 30.0, 3.0)):
        if getattr(args, name) is None:
            setattr(args, name, tiny if args.quick else full)
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
    for name in ('repeats', 'dsdv_repeats', 'executor_nodes', 'eval_agents', 'issue_trials',
                 'issue_workers'):
        if getattr(args, name) < 1:
            raise BenchError(f'--{name.replace("_", "-")} must be at least 1')
    args.world_size_list = sizes_arg(args.world_sizes, '--world-sizes', 1)
    for name in ('eval_duration', 'world_seconds', 'executor_seconds', 'ros_duration',
                 'dsdv_limit', 'ros_timeout', 'large_duration'):
        if not getattr(args, name) > 0:
            raise BenchError(f'--{name.replace("_", "-")} must be positive')
    if args.large_agents < 10:
        raise BenchError('--large-agents must be at least 10')
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
    """``benchmarks``: measure the sections, write benchmarks.json and benchmarks.md."""
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
        ('throughput', lambda: s.__setitem__('throughput', bench_throughput(
            args.issue_trials, args.issue_workers, args.large_agents, args.large_duration,
            args.seed, args.quick))),
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
