"""Generalization study: the thesis scenario on procedural shapes nobody tuned for.

  scripts/env.sh python scripts/shape_study.py --shapes 30 --seed 1 --workers 2 \\
      --out results/shape_study

Draws --shapes shapes with ``swarm_mission.shape_gen`` (cycling through blob, concave,
spiral, holes, neck and obstacles, sized 6.28 m^2 a robot), runs every one headless
(``swarm_eval.shape_study``: the thesis scenario, 50 agents, 8 beacons, types 20/20/10 by
default) for each of --methods, and writes into --out:

  <shape>.json      the shape (load_shape layout), its rows and, for a run that did not
                    settle, the diagnosis (unsettled agents, goals short of beacons,
                    worst localization error)
  <shape>.md        its table: settled and held, settling / least settling,
                    displacement / bound, eps_t, eps_g, min separation, contacts, max
                    localization error, agreement, and a note (refusal reason, error or
                    the agents that did not settle)
  shapes/<shape>.json  the shape file the ROS launcher reads
  study.json, study.md  every row and the per-method summary

With --ros-subset K the first K shapes also run through ROS (``scripts/launch_swarm.py``,
--ros-agents agents and --ros-beacons beacons, bubble packing, composed and
per-process), one at a time, each drawn again with the same kind and seed but sized for
the ROS swarm (shapes/<shape>_ros.json); their rows join the tables with method
``bubble/ros-composed`` and ``bubble/ros-per-process``, the launcher's output in
ros/<shape>_<mode>/.
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import json
import os
import pathlib
import subprocess
import sys

from swarm_common.robot_types import default_type_counts, RobotTypeError
from swarm_common.shapes import shape_json
from swarm_eval.paths import repo_root
from swarm_eval.shape_study import (
    markdown_table,
    METHODS,
    row_from_metrics,
    run_trial,
    StudyTrial,
    summary,
    summary_table,
)
from swarm_mission.shape_gen import KINDS, ShapeGenError, study_shapes
from swarm_sim.report import dumps

ROOT = repo_root()
LAUNCHER = ROOT / 'scripts' / 'launch_swarm.py'


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--shapes', type=int, default=6, help='number of generated shapes')
    p.add_argument('--seed', type=int, default=0, help='shape seed; shape i runs fleet seed '
                                                       'SEED + i')
    p.add_argument('--methods', nargs='+', choices=METHODS, default=list(METHODS))
    p.add_argument('--agents', type=int, default=50)
    p.add_argument('--beacons', type=int, default=8)
    p.add_argument('--workers', type=int, default=2, help='local worker processes')
    p.add_argument('--duration', type=float, default=600.0,
                   help='simulated seconds at most per trial')
    p.add_argument('--ros-subset', type=int, default=0, metavar='K',
                   help='also run the first K shapes through ROS (composed and '
                        'per-process)')
    p.add_argument('--ros-agents', type=int, default=16)
    p.add_argument('--ros-beacons', type=int, default=4)
    p.add_argument('--ros-duration', type=float, default=400.0,
                   help='simulated seconds at most per ROS run')
    p.add_argument('--out', required=True, help='results directory')
    return p.parse_args(argv)


def check(args: argparse.Namespace) -> None:
    """Raise ValueError (one line) for a bad request, before anything runs."""
    if args.shapes < 1 or args.workers < 1:
        raise ValueError('--shapes and --workers must be at least 1')
    if args.agents < 1 or not 0 <= args.beacons <= args.agents:
        raise ValueError(f'--agents {args.agents} and --beacons {args.beacons}: give at '
                         'least one agent and 0..agents beacons')
    if not args.duration > 0:
        raise ValueError(f'--duration must be positive, got {args.duration:g}')
    if not 0 <= args.ros_subset <= args.shapes:
        raise ValueError(f'--ros-subset {args.ros_subset} must be within 0 and --shapes '
                         f'{args.shapes}')


def ros_rows(shape, kind: str, shape_file: pathlib.Path, out: pathlib.Path,
             args: argparse.Namespace, seed: int) -> list[dict]:
    """Run ``shape`` through launch_swarm.py composed and per-process; one row each."""
    rows = []
    for mode in ('composed', 'per-process'):
        run_dir = out / 'ros' / f'{shape.name}_{mode}'
        cmd = [sys.executable, str(LAUNCHER), '--agents', str(args.ros_agents),
               '--beacons', str(args.ros_beacons), '--method', 'bubble',
               '--shape', str(shape_file), '--duration', str(args.ros_duration),
               '--seed', str(seed), '--no-record', '--out', str(run_dir)]   # no bag
        if mode == 'composed':
            cmd.append('--composed')
        print(f'shape_study: ROS {mode} on {shape.name} ...', flush=True)
        proc = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ))
        (run_dir).mkdir(parents=True, exist_ok=True)
        (run_dir / 'launcher.log').write_text(proc.stdout + proc.stderr, encoding='utf-8')
        metrics_file = run_dir / 'metrics.json'
        method = f'bubble/ros-{mode}'
        if not metrics_file.exists():
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ['no output']
            rows.append(row_from_metrics(shape, kind, method, seed, 'error', {},
                                         f'{args.ros_agents} agents: launcher exit '
                                         f'{proc.returncode}: {tail[0]}'))
            continue
        metrics = json.loads(metrics_file.read_text(encoding='utf-8'))['trials'][0]
        settled = metrics.get('settled', metrics.get('settling_time') is not None)
        note = f'{args.ros_agents} agents, {args.ros_beacons} beacons, {shape.area:.0f} m^2'
        if proc.returncode != 0:
            note += f'; launcher exit {proc.returncode}'
        rows.append(row_from_metrics(shape, kind, method, seed,
                                     'settled' if settled else 'not settled', metrics, note))
    return rows


def write_shape(out: pathlib.Path, shape, kind: str, rows: list[dict]) -> None:
    """DIR/<shape>.json and DIR/<shape>.md."""
    payload = {'shape': shape.name, 'kind': kind, 'area': shape.area,
               'geometry': shape_json(shape), 'rows': rows}
    (out / f'{shape.name}.json').write_text(dumps(payload, indent=2),
                                            encoding='utf-8')
    (out / f'{shape.name}.md').write_text(
        f'# {shape.name} ({kind}, {shape.area:.0f} m^2)\n\n' + markdown_table(rows),
        encoding='utf-8')


def main(argv: list[str] | None = None) -> int:
    """``shape_study``: run every shape and method, write the tables."""
    args = parse_args(argv)
    try:
        check(args)
        counts = default_type_counts(args.agents)
        shapes = study_shapes(args.shapes, args.seed, args.agents)
    except (ValueError, RobotTypeError, ShapeGenError) as exc:
        print(f'shape_study.py: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    (out / 'shapes').mkdir(parents=True, exist_ok=True)
    (out / 'rows').mkdir(exist_ok=True)
    kinds = {s.name: KINDS[i % len(KINDS)] for i, s in enumerate(shapes)}
    for shape in shapes:
        (out / 'shapes' / f'{shape.name}.json').write_text(json.dumps(shape_json(shape)),
                                                           encoding='utf-8')
    trials = [StudyTrial(shape, kinds[shape.name], method, args.seed + i, counts,
                         args.beacons, args.duration)
              for i, shape in enumerate(shapes) for method in args.methods]
    rows: dict[str, list[dict]] = {s.name: [] for s in shapes}
    from tqdm import tqdm

    with futures.ProcessPoolExecutor(max_workers=args.workers) as pool:
        jobs = {pool.submit(run_trial, t): t for t in trials}
        for job in tqdm(futures.as_completed(jobs), total=len(jobs), unit='trial'):
            trial = jobs[job]
            try:
                row = job.result()
            except Exception as exc:    # a worker that died: still a row
                row = row_from_metrics(trial.shape, trial.kind, trial.method, trial.seed,
                                       'error', {}, f'{type(exc).__name__}: {exc}')
            rows[trial.shape.name].append(row)
            # Every row on disk as it comes: an interrupted study keeps what it ran.
            (out / 'rows' / f'{row["shape"]}_{row["method"]}.json').write_text(
                dumps(row), encoding='utf-8')
            tqdm.write(f'{row["shape"]} {row["method"]}: {row["status"]} {row["note"]}')
    # The ROS swarm is smaller: the same kinds and seeds, sized for --ros-agents.
    for i, shape in enumerate(study_shapes(args.ros_subset, args.seed, args.ros_agents)):
        shape_file = out / 'shapes' / f'{shape.name}_ros.json'
        shape_file.write_text(json.dumps(shape_json(shape)), encoding='utf-8')
        rows[shape.name] += ros_rows(shape, kinds[shape.name], shape_file, out, args,
                                     args.seed + i)
    order = {m: k for k, m in enumerate(args.methods)}
    every = []
    for shape in shapes:
        mine = sorted(rows[shape.name], key=lambda r: (order.get(r['method'], 99),
                                                       r['method']))
        write_shape(out, shape, kinds[shape.name], mine)
        every += mine
    summ = summary(every)
    (out / 'study.json').write_text(dumps(
        {'arguments': vars(args), 'summary': summ, 'rows': every}, indent=2),
        encoding='utf-8')
    (out / 'study.md').write_text(
        f'# Shape study: {args.shapes} shapes, seed {args.seed}, {args.agents} agents, '
        f'{args.beacons} beacons\n\n' + summary_table(summ) + '\n' + markdown_table(every),
        encoding='utf-8')
    print(summary_table(summ), end='')
    print(f'shape_study.py: {len(every)} rows -> {out / "study.md"}')
    return 0



if __name__ == '__main__':
    sys.exit(main())
