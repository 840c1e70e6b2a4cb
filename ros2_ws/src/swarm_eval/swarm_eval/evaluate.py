"""Headless Monte Carlo evaluation of a formation method (thesis 4.3).

Runs T trials of the scenario with random initial positions in the +/-50 m workspace,
with the same brains, radio medium, partitioners and sensor models as the ROS system
(``swarm_sim.headless``), and writes into --out:

  metrics.json      {"trials": [{...}, ...], "mean": {...}, "scenario": {...}}; with
                    --sequence or --morph also coverage_lags and dispersion_during_change
                    (swarm_sim.metrics.change_metrics)
  table.md          a table like thesis Tables 4.5-4.9
  boxplots.png      total displacement, settling time, epsilon_t, epsilon_g (Figs. 4.17-4.34)
  trajectories.png  the first trial's true trajectories, shape and final goals

and, as the run goes (a killed evaluator leaves all but the last --record-flush
seconds): trials.jsonl, one line of metrics per finished trial, and
records/trial_SEED.jsonl, each trial's record (swarm_sim.run_record.RecordLog; read it
back, also cut, with ``read_record_log``; --no-records leaves them out).

The trials run on --workers local processes or, with --dask ADDRESS, on a Dask cluster
(``dask.distributed.Client(ADDRESS)``; ``--dask local`` starts a LocalCluster of --workers
single-threaded processes). A trial depends only on its seed, so both give the same
per-trial metrics for the same seeds (only the wall-clock figures differ). Workers of a
remote cluster need the swarm_* packages importable (the same environment).

Examples (``ros2 run swarm_eval evaluate`` takes the same arguments):
  scripts/env.sh python scripts/evaluate.py --method bubble --shape circle_314 \\
      --agents 50 --beacons 8 --trials 4 --workers 2 --out results/eval_bubble
  scripts/env.sh python scripts/evaluate.py --trials 20 --dask tcp://scheduler:8786 \\
      --out results/eval_dask
"""

from __future__ import annotations

import argparse
import contextlib
import pathlib
import sys

from swarm_common.robot_types import RobotTypeError
from swarm_common.shapes import ShapeError
from swarm_eval.scenario import build_scenario, ScenarioSpec
from swarm_eval.trials import dask_client, dask_trials, DaskError, local_trials
from swarm_mission.mission import REMESH
from swarm_mission.partition import PartitionError
from swarm_sim import plots
from swarm_sim.headless import ScenarioError
from swarm_sim.report import dumps, run_report, write_metrics
from swarm_sim.run_record import FLUSH_PERIOD_S

BOX_KEYS = (('total_displacement', 'total displacement [m]'),
            ('settling_time', 'settling time [s]'), ('epsilon_t', 'epsilon_t'),
            ('epsilon_g', 'epsilon_g'))
DEFAULTS = ScenarioSpec()


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--method', choices=('bubble', 'fractal', 'forces'),
                        default=DEFAULTS.method)
    parser.add_argument('--shape', default=DEFAULTS.shape,
                        help='built-in shape name or .json/.svg/.png file')
    parser.add_argument('--shape-scale', type=float, default=DEFAULTS.shape_scale)
    parser.add_argument('--agents', type=int, default=DEFAULTS.agents)
    parser.add_argument('--types', default='',
                        help='composition TYPE:COUNT,... (default: the thesis 40/40/20 %%)')
    parser.add_argument('--beacons', type=int, default=None,
                        help='beacon count (default: 15 %% of the agents, as in the thesis)')
    parser.add_argument('--trials', type=int, default=1)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--workers', type=int, default=1,
                        help='local worker processes (also the size of --dask local)')
    parser.add_argument('--dask', default='', metavar='ADDRESS',
                        help="run the trials on the Dask scheduler at ADDRESS (e.g. "
                             "tcp://host:8786), or 'local' for a LocalCluster of --workers "
                             'processes')
    parser.add_argument('--duration', type=float, default=DEFAULTS.duration,
                        help='maximum simulated seconds per trial')
    parser.add_argument('--settle-hold', type=float, default=DEFAULTS.settle_hold,
                        help='seconds the settled condition (eq. 4.1) must hold before a '
                             'trial ends settled')
    parser.add_argument('--sequence', default='', help='YAML/JSON shape sequence file')
    parser.add_argument('--morph', default='', metavar='KIND:AMOUNT@START+DURATION',
                        help='a smooth shape change (move metres along x or by DX,DY, rotate '
                             'degrees, grow by 1+AMOUNT), e.g. move:15@150+60; not with '
                             '--sequence')
    parser.add_argument('--remesh', choices=REMESH, default=DEFAULTS.remesh,
                        help='bubble packing on a changed shape: goals move keeping their '
                             'ids (incremental) or are partitioned anew and re-assigned')
    parser.add_argument('--remove', action='append', default=[],
                        help='remove agents mid-run, e.g. --remove 60:3,17 (time:ids)')
    parser.add_argument('--loss', type=float, default=DEFAULTS.loss, help='radio packet loss 0..1')
    parser.add_argument('--control-rate', type=float,
                        default=DEFAULTS.control_rate,
                        help='inner loop rate in Hz')
    parser.add_argument('--swarm-key-file', default='',
                        help='swarm key file of the authenticated radio frames (default: '
                             'the development key, docs/security.md)')
    parser.add_argument('--no-auth', dest='auth', action='store_false',
                        help='unauthenticated radio frames (only to compare with and without)')
    parser.add_argument('--record-flush', type=float, default=FLUSH_PERIOD_S, metavar='S',
                        help='wall seconds between flushes of the records to disk (the '
                             'most a killed evaluator loses)')
    parser.add_argument('--no-records', dest='records', action='store_false',
                        help='no per-trial records (records/trial_SEED.jsonl)')
    parser.add_argument('--out', required=True, help='results directory')
    return parser.parse_args(argv)



def write_table(path: pathlib.Path, method: str, mean: dict) -> None:
    """A markdown table like thesis Tables 4.5-4.9."""
    def fmt(key: str, digits: int) -> str:
        v = mean.get(key)
        return f'{v:.{digits}f}' if v is not None else 'n/a'

    lines = ['| Method | Settled | Total displacement [m] | Lower bound [m] | '
             'Settling time [s] | Least settling [s] | Settling ratio | eps_t | eps_g | '
             'Min separation | Contacts |',
             '|---|---|---|---|---|---|---|---|---|---|---|',
             f'| {method} | {fmt("settled_fraction", 2)} | {fmt("total_displacement", 0)} | '
             f'{fmt("displacement_lower_bound", 0)} | {fmt("settling_time", 0)} | '
             f'{fmt("least_settling_time", 0)} | {fmt("settling_ratio", 2)} | '
             f'{fmt("epsilon_t", 2)} | {fmt("epsilon_g", 2)} | '
             f'{fmt("min_separation_ratio", 2)} | {fmt("contacts", 1)} |']
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')


def figures(out: pathlib.Path, trials: list[dict], record, method: str) -> None:
    """Box plots over trials and the first trial's run figures."""
    plots.boxplots(out / 'boxplots.png', {method: trials}, BOX_KEYS)
    run_report(out, vars(record), record.types, record.beacons,
               [shape for _, shape in record.shapes], record.goals)


def main(argv: list[str] | None = None) -> int:
    """``evaluate``: run the trials, write metrics.json, table.md and the figures."""
    args = parse_args(argv)
    out = pathlib.Path(args.out)
    try:
        if args.trials < 1 or args.workers < 1:
            raise ScenarioError('--trials and --workers must be at least 1')
        if not 0.0 < args.record_flush <= 60.0:
            raise ScenarioError(f'--record-flush {args.record_flush:g}: give wall seconds '
                                f'in (0, 60], e.g. {FLUSH_PERIOD_S:g}')
        spec = ScenarioSpec.from_namespace(args)
        build_scenario(spec, args.seed).validate()
    except (ShapeError, ScenarioError, RobotTypeError, PartitionError) as exc:
        print(f'evaluate.py: {exc}', file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    seeds = [args.seed + k for k in range(args.trials)]
    from tqdm import tqdm

    trials: list[dict] = []
    first = None
    record_dir = str((out / 'records').resolve()) if args.records else ''
    try:
        with contextlib.ExitStack() as stack:
            done = stack.enter_context(open(out / 'trials.jsonl', 'w', encoding='utf-8'))
            if args.dask:
                client = stack.enter_context(dask_client(args.dask, args.workers))
                records = dask_trials(client, spec, seeds, record_dir, args.record_flush)
            else:
                records = local_trials(spec, seeds, args.workers, record_dir,
                                       args.record_flush)
            stack.enter_context(contextlib.closing(records))
            for record in tqdm(records, total=len(seeds), unit='trial',
                               desc=f'{args.method} x{args.agents}'):
                trials.append(record.metrics)
                done.write(dumps(record.metrics) + '\n')
                done.flush()
                if record.metrics['seed'] == seeds[0]:
                    first = record
    except (PartitionError, ShapeError, ScenarioError, DaskError) as exc:
        print(f'evaluate.py: {exc}', file=sys.stderr)
        return 2
    trials.sort(key=lambda t: t['seed'])
    mean = write_metrics(out, trials, vars(args))
    write_table(out / 'table.md', args.method, mean)
    figures(out, trials, first, args.method)
    settled = sum(bool(t.get('settled')) for t in trials)
    print(f'{args.method}: {len(trials)} trials, {settled} settled and held '
          f'{args.settle_hold:g} s, displacement '
          f'{mean.get("total_displacement", float("nan")):.0f} m '
          f'(bound {mean.get("displacement_lower_bound", float("nan")):.0f} m), settling '
          f'{mean.get("settling_time", float("nan")):.0f} s '
          f'({mean.get("settling_ratio", float("nan")):.2f} x the least), eps_t '
          f'{mean.get("epsilon_t", float("nan")):.2f}, eps_g '
          f'{mean.get("epsilon_g", float("nan")):.2f}, min separation '
          f'{min(t["min_separation_ratio"] for t in trials):.2f} of the summed radii, '
          f'{sum(t["contacts"] for t in trials)} contacts -> {out}')
    return 0



if __name__ == '__main__':
    sys.exit(main())
