"""Localization error in the thesis scenario per localization period (thesis 4.2, Figs. 4.4-4.6).

A trial is one headless run of the thesis scenario (``swarm_sim.headless``: 50 agents,
8 of them position beacons that move to their goals like the others, random start in
the +/-50 m workspace, the 25 m radio range with line of sight), so agents out of range
of three beacons, LOST and RETURN_HOME all happen as they do in a real run. Only the
fix that an agent's localization tick feeds its Kalman filter depends on the noise
profile:

- ``toa``: the system's own localization. The agent trilaterates TOA ranges (0.3 m
  noise, ``RadioMedium.toa_ranges``) against the positions its beacon neighbours
  broadcast, which are their GPS-fed estimates (``AgentBrain._localize``).
- ``thesis``: the thesis's simulation (3.1.4 eq. 3.32, 4.2): whenever the agent has
  the three beacon neighbours a trilateration needs, the fix is its true position plus
  2 m of Gaussian noise per axis (``sensors.TrilaterationFixModel``), fused as a
  position measurement of that covariance. Without them it misses the tick: LOST,
  then RETURN_HOME after three misses whatever its uncertainty (3.1.3, the thesis's
  rule; ``toa`` goes home only once the estimate is uncertain, see
  ``LocalizationConfig.home_position_std``).

A ``FixProbe`` wraps each non-beacon agent's ``Localizer.localize``: it supplies the
thesis fix, records the time of the agent's first fix and its error just before every
later tick (the peaks of Figs. 4.4-4.6, which come "at the iterations just before the
localization process"). The error statistics are over the non-beacon agents at every
2 Hz record sample (the thesis's propagation rate) from each agent's first fix on;
the maximum also includes the pre-tick errors.

Command line (``main``; ``ros2 run swarm_eval localization_study``, or
``scripts/localization_study.py``) writes into --out:

  error.png      error norm over time per period: every agent of every seed thin, the
                 mean over them bold, the thesis's bound dashed
  summary.json   {"noise": ..., "periods": {"3": {"max_error": m, "p95_error": m,
                 "rms_error": m, "lost_or_home_share": ..., ...}, ...}, ...}

  scripts/env.sh python scripts/localization_study.py --periods 3 5 8 --seeds 3 \\
      --duration 200 --noise thesis --out results/loc_thesis
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
import dataclasses
from dataclasses import dataclass, field
import json
import math
import pathlib
import sys

import numpy as np

from swarm_agent.localization import Localizer, Mode
from swarm_common.robot_types import default_type_counts
from swarm_common.shapes import load_shape, ShapeError
from swarm_sim.headless import HeadlessSwarm, Scenario, ScenarioError, TrialRecord
from swarm_sim.sensors import TrilaterationFixModel

NOISE_PROFILES = ('thesis', 'toa')
THESIS_FIX_STD_M = 2.0                                 # thesis 4.2
THESIS_BOUNDS = {3.0: 3.0, 5.0: 10.0, 8.0: 12.0}       # m: "below 3/10/12 m" (thesis 4.2)


class StudyError(ValueError):
    """A study setup that cannot run (unknown noise profile, bad period, ...)."""


class FixProbe:
    """Stands in for one agent's ``Localizer.localize``; see the module docstring.

    ``truth`` returns the agent's true position now; ``fix_model`` is None for the
    ``toa`` profile (the localizer's own trilateration runs unchanged).
    """

    def __init__(self, localizer: Localizer, truth: Callable[[], np.ndarray],
                 fix_model: TrilaterationFixModel | None) -> None:
        self.localizer = localizer
        self.truth = truth
        self.fix_model = fix_model
        self._localize = localizer.localize
        self.first_fix: float | None = None
        self.pre_tick_errors: list[float] = []   # error just before each tick after the first fix
        self.fixes = 0
        self.misses = 0

    def install(self) -> None:
        """Route the brain's localization ticks through this probe (with the thesis's
        return-home rule for the thesis fix)."""
        self.localizer.localize = self
        if self.fix_model is not None:
            self.localizer.config = dataclasses.replace(self.localizer.config,
                                                        home_position_std=0.0)

    def __call__(self, t: float, beacons: Sequence[tuple[np.ndarray, float, float]],
                 displacement=(0.0, 0.0), secondary=()) -> Mode:
        """A tick; ``secondary`` anchors reach the localizer's own trilateration (``toa``)
        and not the thesis's fix model (3.1.4 fixes from beacons alone)."""
        loc = self.localizer
        truth = np.asarray(self.truth(), dtype=float)
        if self.first_fix is not None:
            self.pre_tick_errors.append(float(np.hypot(*(loc.position - truth))))
        if self.fix_model is None:
            before = loc.stats['localizations']
            mode = self._localize(t, beacons, displacement, secondary=secondary)
            fixed = loc.stats['localizations'] > before
        else:
            usable = sum(1 for p, r, s in beacons if np.all(np.isfinite(p))
                         and math.isfinite(r) and math.isfinite(s) and s > 0)
            if usable >= loc.config.min_beacons:
                fix, std = self.fix_model.measure(truth)
                loc.gps_update(t, fix, std)     # a position measurement of covariance std^2 I
                mode, fixed = loc.mode, True
            else:                               # the localizer's own miss: LOST, RETURN_HOME
                mode, fixed = self._localize(t, [], displacement), False
        if fixed:
            self.fixes += 1
            if self.first_fix is None:
                self.first_fix = t
        else:
            self.misses += 1
        return mode


@dataclass
class TrialResult:
    """One trial: the 2 Hz record, and per non-beacon agent its probe's findings."""

    record: TrialRecord
    seed: int
    period: float                        # localization period (s)
    agents: np.ndarray                   # (M,) indices of the non-beacon agents
    first_fix: np.ndarray                # (M,) time of the first fix, inf when none
    pre_tick_errors: list[np.ndarray]    # per agent
    fixes: int
    misses: int


@dataclass
class StudyConfig:
    """The scenario of every trial: the thesis scenario of chapter 4 by default."""

    agents: int = 50
    beacons: int = 8
    shape: str = 'circle_314'
    method: str = 'bubble'
    imu_period_s: float = 0.1            # sim_node's 10 Hz IMU
    fix_std_m: float = THESIS_FIX_STD_M
    half_size: float = 50.0
    extra: dict = field(default_factory=dict)   # further Scenario fields

    def validate(self, periods: Sequence[float], noise: str, seeds: int,
                 duration: float) -> None:
        if noise not in NOISE_PROFILES:
            raise StudyError(f'unknown noise profile {noise!r}; use one of '
                             f'{", ".join(NOISE_PROFILES)}')
        if seeds <= 0 or duration <= 0 or self.imu_period_s <= 0 or not periods \
                or min(periods) <= 0:
            raise StudyError('--seeds, --duration, --imu-period and --periods must be positive')
        if duration < max(periods):
            raise StudyError(f'--duration {duration:g} s is shorter than the longest period '
                             f'{max(periods):g} s; no localization would happen')
        if not 3 <= self.beacons <= self.agents - 1:
            raise StudyError(f'{self.beacons} beacons among {self.agents} agents: a '
                             f'trilateration needs 3 beacons and the study at least one '
                             f'other agent; use --beacons 3..{self.agents - 1}')
        if not self.fix_std_m > 0:
            raise StudyError(f'fix noise must be positive, got {self.fix_std_m} m')


def run_trial(period: float, noise: str, seed: int, duration: float,
              config: StudyConfig | None = None) -> TrialResult:
    """One headless run of the scenario with localization period ``period``."""
    config = config or StudyConfig()
    scenario = Scenario(
        shape=load_shape(config.shape), method=config.method,
        type_counts=default_type_counts(config.agents), n_beacons=config.beacons,
        seed=seed, duration_s=duration, imu_period_s=config.imu_period_s,
        localization_period_s=period, half_size=config.half_size,
        min_duration_s=duration,          # parked agents count too: no early end
        **config.extra)
    swarm = HeadlessSwarm(scenario)
    fix_rng = np.random.default_rng([seed, 0x10C])
    fix_model = (TrilaterationFixModel(fix_rng, std=config.fix_std_m)
                 if noise == 'thesis' else None)
    agents = np.flatnonzero(~swarm.is_beacon)
    probes = []
    for i in agents:
        probe = FixProbe(swarm.brains[i].localizer,
                         lambda i=i: swarm.dynamics.positions[i], fix_model)
        probe.install()
        probes.append(probe)
    record = swarm.run()
    return TrialResult(
        record=record, seed=seed, period=period, agents=agents,
        first_fix=np.array([np.inf if p.first_fix is None else p.first_fix for p in probes]),
        pre_tick_errors=[np.array(p.pre_tick_errors) for p in probes],
        fixes=sum(p.fixes for p in probes), misses=sum(p.misses for p in probes))


def error_samples(trial: TrialResult) -> tuple[np.ndarray, np.ndarray]:
    """(errors (T, M) of the non-beacon agents with NaN before their first fix or when
    removed, pre-tick errors after the first fix (K,))."""
    rec = trial.record
    err = np.linalg.norm(rec.estimates[:, trial.agents] - rec.positions[:, trial.agents], axis=2)
    valid = rec.alive[:, trial.agents] & (rec.times[:, None] >= trial.first_fix[None, :])
    err = np.where(valid, err, np.nan)
    pre = (np.concatenate(trial.pre_tick_errors) if trial.pre_tick_errors
           else np.zeros(0))
    return err, pre


def steady_mask(trial: TrialResult, periods: float = 3.0) -> np.ndarray:
    """(T, M): the agent has been NORMAL at every record sample of the last ``periods``
    localization periods: it missed no tick (a fix the filter gates leaves the mode as
    it is, so NORMAL does not mean every fix was used)."""
    rec = trial.record
    normal = (rec.modes[:, trial.agents] == Mode.NORMAL) & rec.alive[:, trial.agents]
    run = np.full(normal.shape, -1.0)
    start = np.full(normal.shape[1], np.nan)     # when the current NORMAL spell began
    for k, t in enumerate(rec.times):
        start = np.where(normal[k], np.where(np.isnan(start), t, start), np.nan)
        run[k] = np.where(normal[k], t - start, -1.0)
    return run >= periods * trial.period


def summarize(trials: Sequence[TrialResult]) -> dict:
    """Error and mode statistics over trials of one (period, noise profile).

    Besides the statistics over every sample after the first fix, ``steady_*`` are over
    the samples of agents NORMAL for the last three periods, and
    ``max_error_reacquiring`` over the others (agents coming back from LOST or
    RETURN_HOME, whose grown covariance lets the first fix move them almost all the way).
    """
    samples, pre, lost, home, never = [], [], [], [], 0
    steady, reacquiring, worst = [], [], []
    for trial in trials:
        err, p = error_samples(trial)
        samples.append(err[np.isfinite(err)])
        mask = steady_mask(trial)
        steady.append(err[np.isfinite(err) & mask])
        reacquiring.append(err[np.isfinite(err) & ~mask])
        pre.append(p)
        modes = trial.record.modes[:, trial.agents]
        alive = trial.record.alive[:, trial.agents]
        lost.append(np.sum((modes == Mode.LOST) & alive) / max(alive.sum(), 1))
        home.append(np.sum((modes == Mode.RETURN_HOME) & alive) / max(alive.sum(), 1))
        never += int(np.sum(~np.isfinite(trial.first_fix)))
        if np.isfinite(err).any():
            k, j = np.unravel_index(np.nanargmax(err), err.shape)
            worst.append({'seed': trial.seed, 'agent': int(trial.agents[j]),
                          'time': float(trial.record.times[k]), 'error': float(err[k, j]),
                          'steady': bool(mask[k, j])})
    err = np.concatenate(samples)
    pre_all = np.concatenate(pre)
    steady_err = np.concatenate(steady)
    reacq = np.concatenate(reacquiring)
    nan = float('nan')
    fixes = sum(t.fixes for t in trials)
    ticks = fixes + sum(t.misses for t in trials)
    settling = [t.record.metrics.get('settling_time') for t in trials]
    settling = [None if s is None or not np.isfinite(s) else float(s) for s in settling]
    return {
        'max_error': float(max(err.max(initial=0.0), pre_all.max(initial=0.0)))
        if len(err) else nan,
        'p95_error': float(np.percentile(err, 95)) if len(err) else nan,
        'rms_error': float(np.sqrt(np.mean(err ** 2))) if len(err) else nan,
        'mean_error': float(err.mean()) if len(err) else nan,
        'max_pre_tick_error': float(pre_all.max()) if len(pre_all) else nan,
        'steady_max_error': float(steady_err.max()) if len(steady_err) else nan,
        'steady_p95_error': float(np.percentile(steady_err, 95)) if len(steady_err) else nan,
        'steady_rms_error': float(np.sqrt(np.mean(steady_err ** 2))) if len(steady_err) else nan,
        'steady_share': len(steady_err) / len(err) if len(err) else nan,
        'max_error_reacquiring': float(reacq.max()) if len(reacq) else nan,
        'lost_share': float(np.mean(lost)),
        'return_home_share': float(np.mean(home)),
        'lost_or_home_share': float(np.mean(lost) + np.mean(home)),
        'fix_share': fixes / ticks if ticks else nan,
        'agents_never_fixed': never,
        'samples': int(len(err)),
        'worst_per_trial': worst,       # the largest recorded error of each trial
        'settling_time': settling,      # per trial, None when not settled by the end
    }


def study(periods: Sequence[float], noise: str, seeds: int, duration: float,
          config: StudyConfig | None = None,
          progress: Callable[[str], None] | None = None) -> tuple[dict, dict]:
    """Every (period, seed) trial: (summary, curves for plotting).

    ``curves[period]`` is (times (T,), errors (T, seeds * M)) with NaN before each
    agent's first fix.
    """
    config = config or StudyConfig()
    config.validate(periods, noise, seeds, duration)
    summary: dict = {
        'noise': noise, 'seeds': seeds, 'duration_s': duration, 'agents': config.agents,
        'beacons': config.beacons, 'shape': config.shape, 'method': config.method,
        'imu_period_s': config.imu_period_s,
        'fix_std_m': config.fix_std_m if noise == 'thesis' else None,
        'thesis_max_error_m': {_key(p): b for p, b in THESIS_BOUNDS.items()},
        'periods': {}}
    curves = {}
    for period in periods:
        trials = [run_trial(period, noise, seed, duration, config) for seed in range(seeds)]
        stats = summarize(trials)
        summary['periods'][_key(period)] = stats
        length = min(len(t.record.times) for t in trials)
        curves[_key(period)] = (
            trials[0].record.times[:length],
            np.concatenate([error_samples(t)[0][:length] for t in trials], axis=1))
        if progress is not None:
            progress(f'period {period:g} s, {noise}: max error {stats["max_error"]:.2f} m, '
                     f'p95 {stats["p95_error"]:.2f} m, RMS {stats["rms_error"]:.2f} m, '
                     f'LOST/RETURN_HOME {100 * stats["lost_or_home_share"]:.1f} % of '
                     f'agent-time ({seeds} seeds, {duration:g} s)')
    return summary, curves


def _key(period: float) -> str:
    return f'{period:g}'


def plot(curves: dict, noise: str, path: pathlib.Path) -> None:
    """One panel per period, like Figs. 4.4-4.6."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

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
    """``localization_study``: run the periods and seeds, write error.png and summary.json."""
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
