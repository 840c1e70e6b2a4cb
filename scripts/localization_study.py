#!/usr/bin/env python3
"""Localization-period study in the thesis scenario (thesis 4.2, Figs. 4.4-4.6).

Runs the 50-agent, 8-beacon thesis scenario headless (``swarm_sim.headless``: beacons
move to their goals like every agent, the 25 m radio range, so out-of-range, LOST and
RETURN_HOME cases happen) for every localization timer period and seed, with one of
two fix noise profiles (``swarm_sim.localization_study``):

  thesis  the fix is the true position plus 2 m of Gaussian noise per axis whenever
          three beacons are direct neighbours, as the thesis simulates it (4.2)
  toa     the agent trilaterates 0.3 m TOA ranges against its beacon neighbours'
          broadcast estimates (the system's own localization)

Error statistics are over the non-beacon agents at every 2 Hz record sample from
each agent's first fix on (the maximum also over the errors just before every
localization tick). Writes into --out:

  error.png      error norm over time per period: every agent of every seed thin, the
                 mean over them bold, the thesis's bound dashed
  summary.json   {"noise": ..., "periods": {"3": {"max_error": m, "p95_error": m,
                 "rms_error": m, "lost_or_home_share": ..., ...}, ...}, ...}

Example:
  scripts/env.sh python scripts/localization_study.py --periods 3 5 8 --seeds 3 \\
      --duration 200 --noise thesis --out results/loc_thesis
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

from swarm_mission.shapes import ShapeError  # noqa: E402
from swarm_sim.headless import ScenarioError  # noqa: E402
from swarm_sim.localization_study import (  # noqa: E402
    NOISE_PROFILES,
    study,
    StudyConfig,
    StudyError,
    THESIS_BOUNDS,
)


def plot(curves: dict, noise: str, path: pathlib.Path) -> None:
    """One panel per period, like Figs. 4.4-4.6."""
    fig, axes = plt.subplots(len(curves), 1, figsize=(8, 2.6 * len(curves)), sharex=True,
                             squeeze=False)
    for ax, (key, (times, err)) in zip(axes[:, 0], curves.items()):
        ax.plot(times, err, lw=0.4, alpha=0.3, color='tab:blue')
        fixed = np.isfinite(err)
        count = fixed.sum(axis=1)
        mean = np.where(count > 0, np.where(fixed, err, 0.0).sum(axis=1) / np.maximum(count, 1),
                        np.nan)
        ax.plot(times, mean, lw=1.6, color='tab:red', label='mean over agents and seeds')
        bound = THESIS_BOUNDS.get(float(key))
        if bound is not None:
            ax.axhline(bound, ls='--', color='k', lw=0.8, label=f'thesis bound {bound:g} m')
        ax.set_ylabel('|error| (m)')
        ax.set_title(f'Localization timer period {key} s, {noise} noise (thesis Figs. 4.4-4.6)')
        ax.grid(alpha=0.3)
        ax.legend(loc='upper right', fontsize=8)
    axes[-1, 0].set_xlabel('time (s)')
    axes[-1, 0].set_xlim(0.0, max(float(t[-1]) for t, _ in curves.values()))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--periods', type=float, nargs='+', default=[3.0, 5.0, 8.0],
                        help='localization timer periods (s)')
    parser.add_argument('--seeds', type=int, default=3)
    parser.add_argument('--duration', type=float, default=200.0, help='seconds per trial')
    parser.add_argument('--noise', choices=NOISE_PROFILES, default='thesis',
                        help='fix noise profile: thesis (2 m on the fix) or toa (ranges)')
    parser.add_argument('--agents', type=int, default=50, help='agents, beacons included')
    parser.add_argument('--beacons', type=int, default=8)
    parser.add_argument('--shape', default='circle_314',
                        help='built-in shape name or .json/.svg/.png file')
    parser.add_argument('--imu-period', type=float, default=0.1,
                        help="IMU sample period (s); 0.1 as the simulator's 10 Hz IMU")
    parser.add_argument('--out', required=True, help='results directory')
    args = parser.parse_args(argv)
    if args.agents <= 0:
        print('localization_study: error: --agents must be positive', file=sys.stderr)
        return 2
    config = StudyConfig(agents=args.agents, beacons=args.beacons, shape=args.shape,
                         imu_period_s=args.imu_period)
    try:
        summary, curves = study(args.periods, args.noise, args.seeds, args.duration, config,
                                progress=lambda line: print(line, flush=True))
    except (StudyError, ScenarioError, ShapeError) as exc:
        print(f'localization_study: error: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(curves, args.noise, out / 'error.png')
    (out / 'summary.json').write_text(json.dumps(summary, indent=2) + '\n')
    print(json.dumps(summary, indent=2))
    print(f'wrote {out / "error.png"} and {out / "summary.json"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
