#!/usr/bin/env python3
"""Localization-period study: estimation error over time for 3, 5, 8 s (thesis Figs. 4.4-4.6).

A few agents drive circles (0.5 m/s, radius 6 m) inside a ring of 8 stationary
position beacons (radius 14 m, all within the 25 m radio range). Everything an agent
runs is the real code: its ``Localizer`` propagates the Kalman filter with the IMU
(``swarm_sim.sensors.ImuModel``: bias up to 0.1 mg, white noise 0.01 m/s^2, thesis
4.2) and at every localization tick trilaterates against the beacons that are its
direct radio neighbours, with TOA ranges from ``swarm_sim.medium.RadioMedium``. The
beacons run their own ``Localizer`` with GPS fixes of 2 m (``GpsModel``) and, parked,
its zero-velocity update at the outer-loop rate as ``AgentBrain`` does; an agent
uses the beacons' *estimates*, their uncertainty added to the range noise, exactly as
``AgentBrain._localize`` does with the positions heard in heartbeats.

The error norm |estimate - truth| is recorded at every IMU sample; max and RMS are
taken from the first localization on (before it, only the 1 m initial error drifts).
Writes into --out:

  error.png      error norm over time per period (every agent of every seed, mean bold)
  summary.json   {"periods": {"3": {"max_error": m, "rms_error": m, ...}, ...}, ...}

Example:
  scripts/env.sh python scripts/localization_study.py --periods 3 5 8 --seeds 10 \\
      --duration 120 --out results/localization_study
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from swarm_agent.brain import BrainConfig  # noqa: E402
from swarm_agent.localization import LocalizationConfig, Localizer, Mode  # noqa: E402
from swarm_sim.medium import MediumConfig, RadioMedium  # noqa: E402
from swarm_sim.sensors import GpsModel, ImuModel  # noqa: E402

THESIS_BOUNDS = {3.0: 3.0, 5.0: 10.0, 8.0: 12.0}  # m: "below 3/10/12 m" (thesis 4.2)


def _key(period: float) -> str:
    return f'{period:g}'


def run_trial(period: float, seed: int, duration: float, agents: int = 3,
              beacons: int = 8, imu_period: float = 0.02, gps_period: float = 1.0,
              speed: float = 0.5, radius: float = 6.0, ring: float = 14.0
              ) -> tuple[np.ndarray, np.ndarray, dict]:
    """One trial: (times (T,), error norms (T, agents), counters)."""
    rng = np.random.default_rng(seed)
    n = agents + beacons
    ids = list(range(n))
    beacon_pos = ring * np.array([[math.cos(a), math.sin(a)] for a in
                                  np.linspace(0.0, 2 * math.pi, beacons, endpoint=False)])
    phase = rng.uniform(0.0, 2 * math.pi, agents)
    centre = rng.uniform(-2.0, 2.0, (agents, 2))
    omega = speed / radius

    def truth(t: float) -> tuple[np.ndarray, np.ndarray]:
        ang = phase + omega * t
        p = centre + radius * np.column_stack([np.cos(ang), np.sin(ang)])
        v = speed * np.column_stack([-np.sin(ang), np.cos(ang)])
        return p, v

    medium = RadioMedium(MediumConfig(), rng)
    imu = ImuModel(n, rng)
    gps = GpsModel(rng)
    config = LocalizationConfig(period_s=period)
    p0, v0 = truth(0.0)
    init_err = rng.normal(0.0, config.initial_position_std, (agents, 2))
    locs = [Localizer(config, p0[i] + init_err[i], initial_velocity=v0[i])
            for i in range(agents)]
    # A beacon starts from one GPS fix, and its filter says how good that is.
    first_fix = LocalizationConfig(period_s=period, initial_position_std=gps.std)
    beacon_locs = [Localizer(first_fix, gps.measure(b)[0]) for b in beacon_pos]
    steps = int(round(duration / imu_period))
    every_gps = max(1, int(round(gps_period / imu_period)))
    every_loc = max(1, int(round(period / imu_period)))
    every_outer = max(1, int(round(BrainConfig.outer_period_s / imu_period)))
    times = np.arange(steps + 1) * imu_period
    errors = np.zeros((steps + 1, agents))
    counters = {'localizations': 0, 'misses': 0, 'beacons_heard': []}
    v_prev = v0
    for k, t in enumerate(times):
        p, v = truth(t)
        if k > 0:
            # mean acceleration over the IMU interval, as sim_node and headless measure it
            true_acc = np.vstack([(v - v_prev) / imu_period, np.zeros((beacons, 2))])
            meas = imu.measure(true_acc)
            for i, loc in enumerate(locs + beacon_locs):
                loc.predict(t, meas[i])
        else:
            for loc in locs + beacon_locs:
                loc.predict(t, (0.0, 0.0))
        v_prev = v
        if k % every_gps == 0:
            for b, loc in zip(beacon_pos, beacon_locs):
                loc.gps_update(t, *gps.measure(b))
        if k % every_outer == 0:
            for loc in beacon_locs:     # parked: AgentBrain's zero-velocity update
                loc.stand_still()
        if k > 0 and k % every_loc == 0:
            medium.update_positions(ids, np.vstack([p, beacon_pos]))
            for i, loc in enumerate(locs):
                heard = []
                for b, rng_m, std in medium.toa_ranges(i, range(agents, n)):
                    est = beacon_locs[b - agents]
                    cov = est.covariance
                    pos_std = math.sqrt(max(0.5 * (cov[0, 0] + cov[1, 1]), 0.0))
                    heard.append((est.position.copy(), rng_m, math.hypot(std, pos_std)))
                counters['beacons_heard'].append(len(heard))
                mode = loc.localize(t, heard)
                counters['localizations' if mode == Mode.NORMAL else 'misses'] += 1
        errors[k] = np.linalg.norm(np.array([loc.position for loc in locs]) - p, axis=1)
    return times, errors, counters


def study(periods: list[float], seeds: int, duration: float, agents: int,
          imu_period: float) -> tuple[dict, dict]:
    """All trials; (summary, curves for plotting)."""
    summary: dict = {'periods': {}, 'seeds': seeds, 'duration_s': duration,
                     'agents': agents, 'imu_period_s': imu_period,
                     'thesis_max_error_m': {_key(p): b for p, b in THESIS_BOUNDS.items()}}
    curves = {}
    for period in periods:
        runs = [run_trial(period, seed, duration, agents, imu_period=imu_period)
                for seed in range(seeds)]
        times = runs[0][0]
        err = np.concatenate([r[1] for r in runs], axis=1)        # (T, seeds * agents)
        heard = [h for r in runs for h in r[2]['beacons_heard']]
        # statistics from the first localization on: before it the error is the
        # initial one (1 m std) drifting, whatever the period
        steady = err[times >= period]
        ticks = np.round(times / imu_period).astype(int) % max(
            1, int(round(period / imu_period))) == 0
        after_fix = err[ticks & (times >= period)]
        summary['periods'][_key(period)] = {
            'max_error': float(steady.max()),
            'rms_error': float(np.sqrt(np.mean(steady ** 2))),
            'mean_error': float(steady.mean()),
            'p95_error': float(np.percentile(steady, 95)),
            'rms_error_after_fix': float(np.sqrt(np.mean(after_fix ** 2))),
            'max_error_before_first_fix': float(err[times < period].max()),
            'localizations': int(sum(r[2]['localizations'] for r in runs)),
            'misses': int(sum(r[2]['misses'] for r in runs)),
            'mean_beacons_heard': float(np.mean(heard)) if heard else 0.0,
        }
        curves[_key(period)] = (times, err)
        s = summary['periods'][_key(period)]
        print(f'period {period:g} s: max error {s["max_error"]:.3f} m, RMS {s["rms_error"]:.3f} m'
              f' ({seeds} seeds x {agents} agents, {duration:g} s)', flush=True)
    return summary, curves


def plot(curves: dict, path: pathlib.Path) -> None:
    """One panel per period: every agent's error norm thin, the mean bold."""
    fig, axes = plt.subplots(len(curves), 1, figsize=(8, 2.6 * len(curves)), sharex=True,
                             squeeze=False)
    for ax, (key, (times, err)) in zip(axes[:, 0], curves.items()):
        ax.plot(times, err, lw=0.4, alpha=0.35, color='tab:blue')
        ax.plot(times, err.mean(axis=1), lw=1.6, color='tab:red', label='mean over agents')
        bound = THESIS_BOUNDS.get(float(key))
        if bound is not None:
            ax.axhline(bound, ls='--', color='k', lw=0.8, label=f'thesis bound {bound:g} m')
        ax.set_ylabel('|error| (m)')
        ax.set_title(f'Localization timer period {key} s (thesis Figs. 4.4-4.6)')
        ax.grid(alpha=0.3)
        ax.legend(loc='upper right', fontsize=8)
    axes[-1, 0].set_xlabel('time (s)')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--periods', type=float, nargs='+', default=[3.0, 5.0, 8.0],
                        help='localization timer periods (s)')
    parser.add_argument('--seeds', type=int, default=5)
    parser.add_argument('--duration', type=float, default=120.0, help='seconds per trial')
    parser.add_argument('--agents', type=int, default=3, help='moving agents per trial')
    parser.add_argument('--imu-period', type=float, default=0.02,
                        help='IMU / propagation period (s); 0.02 as the simulator')
    parser.add_argument('--out', required=True, help='results directory')
    args = parser.parse_args(argv)
    if (args.seeds <= 0 or args.duration <= 0 or args.agents <= 0 or args.imu_period <= 0
            or min(args.periods) <= 0):
        print('localization_study: error: --seeds, --duration, --agents, --imu-period and '
              '--periods must be positive', file=sys.stderr)
        return 2
    if args.duration < max(args.periods):
        print(f'localization_study: error: --duration {args.duration:g} s is shorter than '
              f'the longest period {max(args.periods):g} s; no localization would happen',
              file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, curves = study(args.periods, args.seeds, args.duration, args.agents,
                            args.imu_period)
    plot(curves, out / 'error.png')
    (out / 'summary.json').write_text(json.dumps(summary, indent=2) + '\n')
    print(json.dumps(summary, indent=2))
    print(f'wrote {out / "error.png"} and {out / "summary.json"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
