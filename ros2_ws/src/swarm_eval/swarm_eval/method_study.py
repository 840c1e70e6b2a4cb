"""Compare the three formation methods (thesis Table 4.4) and dynamic formations (4.3.4).

Runs the headless evaluator (``swarm_sim.headless``) for bubble packing, randomized
fractals and artificial forces on the same seeds; then, for bubble packing (incremental
re-mesh, and re-meshed from scratch as the thesis's latency mechanism) and forces, an
abrupt shape switch and smooth shape changes (``--morphs``, 4.3.4's "changed
dynamically in a smooth fashion"). Writes into --out:

  comparison.json   per-method means, the per-trial metrics and the dynamic results
  comparison.md     a table like thesis Tables 4.5-4.9 with the worst-method marks of
                    Table 4.4, and the dynamic-formation table
  boxplots.png      displacement, settling time, epsilon_t, epsilon_g per method
  coverage_lag.png  agents inside the current shape after the switch, and the coverage
                    dispersion through each smooth change (first seed)
  coverage_lag.json lag per switch and method (time until 95 % of the agents are inside)

The response to a smooth change is the trial's ``dispersion_during_change``: the mean
``coverage_dispersion`` (mean distance from the shape in force to the nearest robot, 1
for an even hexagonal spread) from the first change until 20 s after the last.

  scripts/env.sh python scripts/method_study.py --agents 50 --trials 4 --workers 2 \\
      --out results/method_study
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import json
import math
import pathlib
import sys

import numpy as np

from swarm_common.robot_types import default_type_counts
from swarm_common.shapes import load_shape, ShapeError
from swarm_mission.mission import parse_morph, SequenceStep
from swarm_sim import plots
from swarm_sim.headless import HeadlessSwarm, Scenario
from swarm_sim.metrics import CHANGE_WINDOW_S, shape_response
from swarm_sim.report import dumps, summarize

METHODS = ('bubble', 'fractal', 'forces')
# Dynamic formations: (label, method, remesh).
DYNAMIC = (('bubble', 'bubble', 'incremental'), ('bubble, scratch', 'bubble', 'scratch'),
           ('forces', 'forces', 'incremental'))
TABLE_KEYS = (('total_displacement', 'Total displacement [m]', 0, 'min'),
              ('settling_time', 'Settling time [s]', 0, 'min'),
              ('epsilon_t', 'eps_t', 2, 'min'), ('epsilon_g', 'eps_g', 2, 'min'))


def _trial(method: str, shape_name: str, agents: int, beacons: int, seed: int,
           duration: float, sequence: tuple[tuple[float, str], ...] = (),
           morph: str = '', remesh: str = 'incremental', label: str = '',
           dispersion_curve: bool = False) -> dict:
    shape = load_shape(shape_name)
    steps = [SequenceStep(t, load_shape(name)) for t, name in sequence]
    if morph:
        steps = parse_morph(morph, shape)
        # The response is judged up to CHANGE_WINDOW_S after the last change.
        duration = min(duration, steps[-1].time + 2 * CHANGE_WINDOW_S)
    scenario = Scenario(shape=shape, method=method, type_counts=default_type_counts(agents),
                        n_beacons=beacons, seed=seed, duration_s=duration, sequence=steps,
                        remesh=remesh)
    record = HeadlessSwarm(scenario).run()
    result = dict(record.metrics, method=label or method, seed=seed, morph=morph)
    if steps:
        result['coverage'] = response(record, dispersion_curve)
    return result


def response(record, dispersion_curve: bool) -> dict:
    """The whole run's share of agents inside the shape in force and, if
    ``dispersion_curve``, its coverage dispersion (NaN otherwise: a grid query per
    recorded time, about 2 s a trial), for the plots; the metrics come from the trial's
    own record."""
    curves = shape_response(record.times, record.positions, record.alive, record.shapes,
                            start=-math.inf if dispersion_curve else math.inf)
    return {'times': record.times.tolist(), 'fraction_inside': curves['inside'].tolist(),
            'dispersion': curves['dispersion'].tolist(),
            'switch_times': [t for t, _ in record.shapes]}


def _badness(mean: dict, key: str) -> tuple[float, float]:
    """Sort key of a method for the worst-method mark of ``key`` (higher is worse). For
    settling time a method that leaves trials unsettled is worse than any that settles
    them all (its mean is over the settled trials only, or missing)."""
    if key == 'settling_time':
        return -mean.get('settled_fraction', 0.0), mean.get(key, np.inf)
    return 0.0, mean.get(key, -np.inf)


def dynamic_table(dispersion: dict[str, dict[str, list[float]]]) -> list[str]:
    """Markdown rows: mean coverage dispersion through each smooth change per variant,
    the best (lowest) marked."""
    if not dispersion:
        return []
    labels = [label for label, _, _ in DYNAMIC]
    lines = ['', 'Coverage dispersion through each smooth shape change (mean from the first '
             f'change to {CHANGE_WINDOW_S:.0f} s after the last; 1 is an even spread; lower '
             'adapts better):', '', '| Shape change | ' + ' | '.join(labels) + ' |',
             '|---' * (len(labels) + 1) + '|']
    for spec, by_label in dispersion.items():
        means = {label: float(np.mean(v)) if v else np.nan for label, v in by_label.items()}
        best = min(labels, key=lambda m: (np.isnan(means[m]), means[m]))
        cells = [f'{means[m]:.2f}' + (' (best)' if m == best else '') for m in labels]
        lines.append(f'| {spec} | ' + ' | '.join(cells) + ' |')
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--shape', default='thesis_shape_1')
    parser.add_argument('--sequence', nargs='*', default=['thesis_shape_1@0',
                                                          'thesis_shape_2@150'],
                        help='dynamic-formation shapes as NAME@TIME')
    parser.add_argument('--morphs', nargs='*',
                        default=['move:15@200+60', 'rotate:90@200+60', 'grow:0.3@200+60'],
                        help='smooth shape changes of --shape as KIND:AMOUNT@START+DURATION '
                             '(see evaluate.py --morph); none to skip')
    parser.add_argument('--agents', type=int, default=50)
    parser.add_argument('--beacons', type=int, default=8)
    parser.add_argument('--trials', type=int, default=4)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--duration', type=float, default=600.0)
    parser.add_argument('--out', required=True)
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    try:
        load_shape(args.shape)
        sequence = tuple((float(s.split('@')[1]), s.split('@')[0]) for s in args.sequence)
        for _, name in sequence:
            load_shape(name)
        for spec in args.morphs:
            parse_morph(spec, load_shape(args.shape))
    except (ShapeError, IndexError, ValueError) as exc:
        print(f'method_study.py: bad shape or sequence: {exc}', file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    from tqdm import tqdm

    jobs = [(m, args.shape, args.agents, args.beacons, args.seed + k, args.duration, ())
            for m in METHODS for k in range(args.trials)]
    jobs += [(m, sequence[0][1], args.agents, args.beacons, args.seed, args.duration,
              sequence[1:], '', remesh, label) for label, m, remesh in DYNAMIC]
    # Only the first seed's dispersion is plotted.
    jobs += [(m, args.shape, args.agents, args.beacons, args.seed + k, args.duration, (),
              spec, remesh, label, k == 0)
             for spec in args.morphs for label, m, remesh in DYNAMIC
             for k in range(args.trials)]
    results: list[dict] = []
    with futures.ProcessPoolExecutor(max_workers=args.workers) as pool:
        pending = [pool.submit(_trial, *job) for job in jobs]
        for job in tqdm(futures.as_completed(pending), total=len(pending), unit='trial'):
            results.append(job.result())
    static = [r for r in results if 'coverage' not in r]
    dynamic = [r for r in results if 'coverage' in r and not r['morph']]
    morphs = sorted((r for r in results if r.get('morph')), key=lambda r: r['seed'])
    groups = {m: [r for r in static if r['method'] == m] for m in METHODS}
    means = {m: summarize(g) for m, g in groups.items()}
    lines = ['| Method | ' + ' | '.join(label for _, label, _, _ in TABLE_KEYS) +
             ' | Lower bound [m] |', '|---' * (len(TABLE_KEYS) + 2) + '|']
    worst = {key: max(METHODS, key=lambda m, k=key: _badness(means[m], k))
             for key, _, _, _ in TABLE_KEYS}
    for m in METHODS:
        cells = []
        for key, _, digits, _ in TABLE_KEYS:
            v = means[m].get(key)
            mark = ' (worst)' if worst[key] == m else ''
            text = 'never' if v is None else f'{v:.{digits}f}'
            if key == 'settling_time' and means[m]['settled_fraction'] < 1.0:
                text += f' ({means[m]["settled_fraction"]:.0%} settled)'
            cells.append(text + mark)
        bound = means[m].get('displacement_lower_bound')
        bound_cell = 'n/a' if bound is None else f'{bound:.0f}'
        lines.append(f'| {m} | ' + ' | '.join(cells) + f' | {bound_cell} |')
    lags = {r['method']: r['coverage_lags'] for r in dynamic}
    lines += ['', 'Coverage lag after each shape switch (s until 95 % of agents inside): ' +
              ', '.join(f'{m}: {v}' for m, v in lags.items())]
    dispersion = {spec: {label: [r['dispersion_during_change'] for r in morphs
                                 if r['morph'] == spec and r['method'] == label]
                         for label, _, _ in DYNAMIC} for spec in args.morphs}
    lines += dynamic_table(dispersion)
    (out / 'comparison.md').write_text('\n'.join(lines) + '\n', encoding='utf-8')
    (out / 'comparison.json').write_text(dumps(
        {'means': means, 'trials': static, 'coverage_lag': lags,
         'smooth_change_dispersion': dispersion}, indent=2), encoding='utf-8')
    plots.boxplots(out / 'boxplots.png', groups,
                   [(k, label) for k, label, _, _ in TABLE_KEYS])
    if dynamic:
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1 + len(args.morphs), 1, squeeze=False,
                                 figsize=(8, 3.0 * (1 + len(args.morphs))))
        panels = [(axes[0][0], dynamic, 'fraction_inside', 'agents inside current shape',
                   'switch')]
        panels += [(axes[k + 1][0], [r for r in morphs if r['morph'] == spec
                                     and r['seed'] == args.seed],
                    'dispersion', 'coverage dispersion', spec)
                   for k, spec in enumerate(args.morphs)]
        for ax, runs, key, ylabel, title in panels:
            for r in runs:
                ax.plot(r['coverage']['times'], r['coverage'][key], label=r['method'])
            if runs:
                switches = runs[0]['coverage']['switch_times'][1:]
                ax.axvspan(switches[0], switches[-1] + 1e-3, color='0.9')
            ax.set_title(title, fontsize=9)
            ax.set_xlabel('t [s]')
            ax.set_ylabel(ylabel)
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / 'coverage_lag.png', dpi=110)
        plt.close(fig)
        (out / 'coverage_lag.json').write_text(json.dumps(lags, indent=2), encoding='utf-8')
    print('\n'.join(lines))
    return 0



if __name__ == '__main__':
    sys.exit(main())
