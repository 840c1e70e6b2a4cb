"""Monte Carlo mesh study: bubble packing vs randomized fractals over seeds (thesis 4.3.1, 4.3.5).

For every shape and method, partitions the thesis swarm (default 50 agents, 20:20:10)
with seeds 0..S-1 and records epsilon_t and epsilon_g under both definitions of
swarm_mission.mesh_quality (interior nodes of the triangles inside the shape, and the
boundary-counting one). Writes into --out:

  mesh_study.json   per shape and method: mean, std, min, max of every metric
  mesh_study.csv    one row per (shape, method, seed)
  mesh_study.png    boxplots of epsilon_t and epsilon_g per shape and method
  table43.png       epsilon_t against boundary length for the Table 4.3 sequence

Example:
  scripts/env.sh python scripts/mesh_study.py --seeds 20 --out results/mesh_study
  scripts/env.sh python scripts/mesh_study.py --boundary thesis --out results/mesh_thesis
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from swarm_common.robot_types import (  # noqa: E402
    default_type_counts,
    load_robot_types,
    parse_type_counts,
    RobotTypeError,
)
from swarm_common.shapes import load_shape, ShapeError  # noqa: E402
from swarm_mission.bubble_packing import BubbleConfig  # noqa: E402
from swarm_mission.partition import (  # noqa: E402
    METHODS,
    partition,
    PartitionConfig,
    PartitionError,
)

DEFAULT_SHAPES = ('circle_314,thesis_shape_1,thesis_shape_2,thesis_shape_3,thesis_shape_4,'
                  'table43_1,table43_2,table43_3,table43_4')
KEYS = ('epsilon_t', 'epsilon_g', 'epsilon_t_with_boundary', 'epsilon_g_with_boundary',
        'seconds', 'iterations')


def summarise(rows: list[dict]) -> dict:
    """Mean, std, min and max of every metric per shape and method."""
    out: dict = {}
    for row in rows:
        out.setdefault(row['shape'], {}).setdefault(row['method'], []).append(row)
    for methods in out.values():
        for method, group in list(methods.items()):
            methods[method] = {
                k: {'mean': float(np.mean([r[k] for r in group])),
                    'std': float(np.std([r[k] for r in group])),
                    'min': float(np.min([r[k] for r in group])),
                    'max': float(np.max([r[k] for r in group]))} for k in KEYS}
            methods[method]['boundary_length'] = group[0]['boundary_length']
            methods[method]['runs'] = len(group)
    return out


def plot(rows: list[dict], shapes: list[str], path: pathlib.Path) -> None:
    """Boxplots of epsilon_t and epsilon_g per shape, bubble vs fractal."""
    fig, axes = plt.subplots(2, 1, figsize=(max(8, 1.3 * len(shapes)), 8))
    for ax, key in zip(axes, ('epsilon_t', 'epsilon_g')):
        data, labels, colours = [], [], []
        for shape in shapes:
            for method, colour in zip(METHODS, ('tab:blue', 'tab:red')):
                data.append([r[key] for r in rows if r['shape'] == shape
                             and r['method'] == method])
                labels.append(f'{shape}\n{method}')
                colours.append(colour)
        box = ax.boxplot(data, patch_artist=True)
        for patch, colour in zip(box['boxes'], colours):
            patch.set_facecolor(colour)
            patch.set_alpha(0.5)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=6, rotation=60)
        ax.set_ylabel(key)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_table43(summary: dict, path: pathlib.Path) -> None:
    """Epsilon_t (both definitions) against boundary length, Table 4.3 shapes."""
    names = [f'table43_{i}' for i in range(1, 5) if f'table43_{i}' in summary]
    if not names:
        return
    fig, ax = plt.subplots(figsize=(6, 4))
    thesis = {'table43_1': 2.46, 'table43_2': 2.96, 'table43_3': 3.45, 'table43_4': 3.95}
    lengths = [summary[n]['bubble']['boundary_length'] for n in names]
    for key, style in (('epsilon_t', 'o-'), ('epsilon_t_with_boundary', 's--')):
        means = [summary[n]['bubble'][key]['mean'] for n in names]
        stds = [summary[n]['bubble'][key]['std'] for n in names]
        ax.errorbar(lengths, means, yerr=stds, fmt=style, label=f'bubble, {key}')
    ax.plot(lengths, [thesis[n] for n in names], 'k^:', label='thesis Table 4.3')
    ax.set_xlabel('boundary length [m] (area 314 m^2)')
    ax.set_ylabel('epsilon_t')
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--shapes', default=DEFAULT_SHAPES, help='comma-separated shapes')
    parser.add_argument('--seeds', type=int, default=20)
    parser.add_argument('--agents', type=int, default=50)
    parser.add_argument('--types', default='', help='TYPE:COUNT list (default 20:20:10)')
    parser.add_argument('--boundary', choices=('layer', 'mirror', 'thesis'), default=None,
                        help="bubble packing's shape repulsion (default: BubbleConfig's, "
                             "'layer'; 'thesis' is eq. 3.97, the thesis's Table 4.3 trend)")
    parser.add_argument('--out', required=True)
    args = parser.parse_args(argv)
    config = (PartitionConfig(bubble=BubbleConfig(boundary=args.boundary))
              if args.boundary else None)
    if args.seeds <= 0 or args.agents <= 0:
        print('mesh_study: error: --seeds and --agents must be positive', file=sys.stderr)
        return 2
    try:
        counts = parse_type_counts(args.types) if args.types else \
            default_type_counts(args.agents)
        shapes = {name: load_shape(name) for name in args.shapes.split(',') if name}
    except (ShapeError, RobotTypeError) as exc:
        print(f'mesh_study: error: {exc}', file=sys.stderr)
        return 2
    radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
    rows = []
    jobs = [(n, m, s) for n in shapes for m in METHODS for s in range(args.seeds)]
    for name, method, seed in tqdm(jobs, desc='partitions', unit='run'):
        try:
            result = partition(shapes[name], counts, radii, method, seed=seed, config=config)
        except PartitionError as exc:
            print(f'mesh_study: error: {name} {method} seed {seed}: {exc}', file=sys.stderr)
            return 2
        rows.append({'shape': name, 'method': method, 'seed': seed,
                     'boundary_length': shapes[name].boundary_length,
                     **{k: float(getattr(result, k)) for k in KEYS}})
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = summarise(rows)
    (out / 'mesh_study.json').write_text(json.dumps(summary, indent=1))
    with open(out / 'mesh_study.csv', 'w', newline='', encoding='utf-8') as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, list(shapes), out / 'mesh_study.png')
    plot_table43(summary, out / 'table43.png')
    wins = sum(summary[n]['bubble'][k]['mean'] < summary[n]['fractal'][k]['mean']
               for n in summary for k in ('epsilon_t', 'epsilon_g'))
    print(f'mesh_study: {len(rows)} partitions over {len(shapes)} shapes x {args.seeds} seeds; '
          f'bubble packing better on {wins}/{2 * len(summary)} shape-metric means -> {out}')
    return 0



if __name__ == '__main__':
    sys.exit(main())
