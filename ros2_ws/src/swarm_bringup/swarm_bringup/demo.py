"""The main job: the thesis scenario end to end through ROS 2 (``make demo``).

50 agents of the three types of Table 4.1, 8 beacons, bubble packing, a thesis-like
shape among workspace obstacles, then a shape change mid-run (dynamic formation,
thesis 4.3.4). Runs the swarm supervisor (scripts/launch_swarm.py; composed mode by
default, --per-process for one process per agent) and leaves metrics and figures in
--out.
"""

from __future__ import annotations

import argparse
import pathlib

from swarm_bringup import supervisor_node


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', default='results/demo')
    parser.add_argument('--agents', type=int, default=50)
    parser.add_argument('--beacons', type=int, default=8)
    parser.add_argument('--first-shape', default='thesis_shape_1')
    parser.add_argument('--second-shape', default='thesis_shape_2')
    parser.add_argument('--switch-at', type=float, default=150.0, help='sim seconds')
    parser.add_argument('--duration', type=float, default=400.0, help='sim seconds at most')
    parser.add_argument('--per-process', action='store_true',
                        help='one process per agent instead of one composed process')
    return parser.parse_args(argv)


def launch_arguments(args: argparse.Namespace, sequence: pathlib.Path) -> list[str]:
    """The launch_swarm command line of the demo."""
    argv = ['--agents', str(args.agents), '--beacons', str(args.beacons),
            '--method', 'bubble', '--shape', args.first_shape,
            '--sequence', str(sequence), '--duration', str(args.duration),
            '--out', str(args.out)]
    if not args.per_process:
        argv.append('--composed')
    return argv


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sequence = out / 'sequence.yaml'
    sequence.write_text(
        'sequence:\n'
        f'  - {{time: 0, shape: {args.first_shape}}}\n'
        f'  - {{time: {args.switch_at}, shape: {args.second_shape}}}\n', encoding='utf-8')
    print(f'demo: thesis scenario, {args.agents} agents, {args.beacons} beacons, bubble '
          f'packing, {args.first_shape} then {args.second_shape} at t={args.switch_at:.0f} s',
          flush=True)
    return supervisor_node.main(launch_arguments(args, sequence))
