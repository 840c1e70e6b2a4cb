"""Partition a formation shape into typed goal states (thesis 3.2.2.1) and measure the mesh.

Writes into --out:

  goals.json      {"goals": [{"id", "x", "y", "type", "radius"}, ...]} (metres)
  metrics.json    epsilon_t, epsilon_g (and the boundary-counting variants), iterations,
                  converged, seconds, spacing, shape area and boundary length
  partition.png   the shape, coverage circles coloured by type, Delaunay edges

Example:
  scripts/env.sh python scripts/partition.py --method bubble --shape thesis_shape_1 \\
      --agents 50 --types 1:20,2:20,3:10 --seed 0 --out results/partition
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from swarm_common.goals import goal_positions, goals_to_json  # noqa: E402
from swarm_common.robot_types import (  # noqa: E402
    default_type_counts,
    load_robot_types,
    parse_type_counts,
    RobotTypeError,
    TYPE_COLOURS,
)
from swarm_common.shapes import load_shape, ShapeError  # noqa: E402
from swarm_mission.mesh_quality import mesh_triangles  # noqa: E402
from swarm_mission.partition import load_partition_config, METHODS, partition, PartitionError  # noqa: E402


def plot_partition(shape, goals, path: pathlib.Path, title: str) -> None:
    """Shape (blue), obstacles (green), coverage circles by type, Delaunay edges (grey)."""
    fig, ax = plt.subplots(figsize=(7, 7))
    rings = [shape.region.exterior, *shape.region.interiors]
    for ring in rings:
        xy = np.asarray(ring.coords)
        ax.plot(xy[:, 0], xy[:, 1], color='tab:blue', lw=1.5)
    for obstacle in shape.obstacles:
        xy = np.asarray(obstacle.exterior.coords)
        ax.fill(xy[:, 0], xy[:, 1], color='tab:green', alpha=0.4)
    pts = goal_positions(goals)
    triangles, _ = mesh_triangles(pts, shape)
    if len(triangles):
        edges = np.unique(np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1),
                          axis=0)
        for a, b in edges:
            ax.plot(pts[[a, b], 0], pts[[a, b], 1], color='0.6', lw=0.6, zorder=1)
    for g in goals:
        ax.add_patch(plt.Circle((g.x, g.y), g.radius, color=TYPE_COLOURS.get(g.type, 'k'),
                                alpha=0.8, zorder=2))
    for t, colour in TYPE_COLOURS.items():
        ax.plot([], [], 'o', color=colour, label=f'type {t}')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_title(title)
    ax.legend(loc='upper right', fontsize=8)
    if shape.obstacles:
        minx, miny, maxx, maxy = shape.region.bounds
        pad = 0.1 * max(maxx - minx, maxy - miny)
        ax.set_xlim(minx - pad, maxx + pad)
        ax.set_ylim(miny - pad, maxy + pad)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def positive_int(text: str) -> int:
    """argparse type: an integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not an integer') from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f'must be a positive number of agents, got {value}')
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--method', choices=METHODS, default='bubble')
    parser.add_argument('--shape', default='circle_314',
                        help='built-in name or .json/.svg/.png file')
    parser.add_argument('--agents', type=positive_int, default=50)
    parser.add_argument('--types', default='',
                        help='TYPE:COUNT list, e.g. 1:20,2:20,3:10 (default: 20:20:10 split)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--scale', type=float, default=1.0, help='shape scale factor')
    parser.add_argument('--metres-per-pixel', type=float, default=0.05, help='PNG shapes')
    parser.add_argument('--config', default='', help='partition YAML (default: package)')
    parser.add_argument('--out', required=True, help='output directory')
    args = parser.parse_args(argv)
    try:
        counts = parse_type_counts(args.types) if args.types else \
            default_type_counts(args.agents)
        if sum(counts.values()) != args.agents:
            raise RobotTypeError(f'--types sums to {sum(counts.values())} agents but --agents '
                                 f'is {args.agents}; make them agree')
        shape = load_shape(args.shape, scale=args.scale,
                           metres_per_pixel=args.metres_per_pixel)
        radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
        config = load_partition_config(args.config or None)
        result = partition(shape, counts, radii, args.method, seed=args.seed, config=config)
    except (ShapeError, PartitionError, RobotTypeError) as exc:
        print(f'partition: error: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'goals.json').write_text(json.dumps(goals_to_json(result.goals), indent=1))
    metrics = result.metrics() | {'shape': shape.name, 'area': shape.area,
                                  'boundary_length': shape.boundary_length,
                                  'type_counts': {str(k): v for k, v in counts.items()}}
    (out / 'metrics.json').write_text(json.dumps(metrics, indent=1))
    plot_partition(shape, result.goals, out / 'partition.png',
                   f'{args.method} on {shape.name}: eps_t {result.epsilon_t:.2f}, '
                   f'eps_g {result.epsilon_g:.3f}')
    print(f'partition: {args.method} {shape.name} {len(result.goals)} goals in '
          f'{result.seconds:.2f} s ({result.iterations} iterations), eps_t '
          f'{result.epsilon_t:.2f} / {result.epsilon_t_with_boundary:.2f} with boundary, '
          f'eps_g {result.epsilon_g:.3f} / {result.epsilon_g_with_boundary:.3f} -> {out}')
    return 0



if __name__ == '__main__':
    sys.exit(main())
