"""The fault study's per-case summary, markdown table, figure and JSON file."""

from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np

from swarm_sim.report import dumps

MEAN_KEYS = ('fraction_inside', 'goals_claimed', 'goals_reached', 'epsilon_t', 'epsilon_g',
             'assignment_agreement', 'agreement_after_fault', 'final_agreement',
             'duplicate_goal_claims_final', 'duplicate_goal_claims_peak', 'settling_time',
             'recovery_time', 'settled', 'min_separation_ratio', 'min_separation_after_fault',
             'contacts', 'max_hops_seen',
             'routing_loops', 'stale_routes_to_dead', 'max_components_after_fault',
             'beacons_alive', 'min_beacons_heard', 'final_modes_normal', 'passed',
             'duration', 'wall_seconds')



def summarise(rows: list[dict], cases: list[dict]) -> dict[str, dict[str, Any]]:
    """Per-case means (None when no seed had a value), worst separations, pass counts."""
    out: dict[str, dict[str, Any]] = {}
    for case in cases:
        group = [r for r in rows if r['case'] == case['name']]
        if not group:
            continue
        summary: dict[str, Any] = {'seeds': len(group)}
        for key in MEAN_KEYS:
            values = [float(r[key]) for r in group
                      if r.get(key) is not None and not (isinstance(r[key], float)
                                                         and math.isnan(r[key]))]
            summary[key] = float(np.mean(values)) if values else None
        for key in ('min_separation_ratio', 'min_separation_after_fault'):
            # The worst seed; None (in faults.json) is inf: no pair within 3 r_max.
            summary[key] = min(math.inf if r.get(key) is None else float(r[key])
                               for r in group)
        summary['max_hops_seen'] = max(r.get('max_hops_seen', 0) for r in group)
        summary['count_to_infinity'] = any(r.get('count_to_infinity') for r in group)
        summary['passed'] = sum(r['passed'] for r in group)
        summary['target_applies'] = sum(r['target_applies'] for r in group)
        summary['unsettled'] = sum(not r['settled'] for r in group)
        summary['agents'] = max(r.get('agents', 0) for r in group)
        # ROS runs: runs in which a node died (or the run timed out / left no results)
        summary['crashed'] = sum(bool(r.get('crashed')) for r in group)
        summary['frames_rejected'] = rejected_means(group)
        out[case['name']] = summary
    return out


def rejected_means(rows: list[dict]) -> dict[str, float] | None:
    """Frames rejected per seed, by kind (``frame_auth.REJECTIONS``); None when no row
    counted them (a ROS run whose logs held no count)."""
    counted = [r['frames_rejected'] for r in rows if r.get('frames_rejected') is not None]
    if not counted:
        return None
    kinds = sorted({k for c in counted for k in c})
    return {k: float(np.mean([c.get(k, 0) for c in counted])) for k in kinds}


def _fmt_rejected(counts: dict[str, float] | None) -> str:
    if counts is None:
        return 'n/a'
    return ', '.join(f'{k.removeprefix("auth_")} {v:.0f}' for k, v in counts.items()) or '0'


def _fmt(value: Any, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 'n/a'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, int):
        return str(value)
    return f'{value:.{digits}f}'


def markdown_table(summary: dict[str, dict[str, Any]], crashes: bool = False) -> str:
    """One row per case: coverage, agreement, recovery, collisions, DSDV, frames rejected
    by kind (mean per seed), target.

    ``crashes`` adds the column of runs in which a node died (ROS runs).
    """
    head = ('| Case | inside | goals claimed (reached) | eps_t | eps_g | agree (after fault) | '
            'agree (end) | dup claims | settled | recovery [s] | min sep (after fault) | '
            'max hops / N | loops | components | beacons (min heard) | '
            'rejected frames | ' + ('crashed | ' if crashes else '') + 'passed |')
    lines = [head, '|' + '---|' * (head.count('|') - 1)]
    for name, s in summary.items():
        seeds = s['seeds']
        lines.append(
            f'| {name} | {_fmt(s["fraction_inside"])} | {_fmt(s["goals_claimed"])} '
            f'({_fmt(s["goals_reached"])}) | '
            f'{_fmt(s["epsilon_t"])} | {_fmt(s["epsilon_g"])} | '
            f'{_fmt(s["agreement_after_fault"], 3)} | {_fmt(s["final_agreement"], 3)} | '
            f'{_fmt(s["duplicate_goal_claims_final"], 1)} | {seeds - s["unsettled"]}/{seeds} | '
            f'{_fmt(s["recovery_time"], 0)} | {_fmt(s["min_separation_ratio"])} '
            f'({_fmt(s["min_separation_after_fault"])}) | '
            f'{s["max_hops_seen"]} / {s["agents"]} | {_fmt(s["routing_loops"], 1)} | '
            f'{_fmt(s["max_components_after_fault"], 1)} | '
            f'{_fmt(s["beacons_alive"], 1)} ({_fmt(s["min_beacons_heard"], 1)}) | '
            f'{_fmt_rejected(s.get("frames_rejected"))} | '
            + (f'{s["crashed"]}/{seeds} | ' if crashes else '') + f'{s["passed"]}/{seeds} |')
    return '\n'.join(lines) + '\n'


def plot(path: pathlib.Path, summary: dict[str, dict[str, Any]],
         title: str = 'Fault study') -> None:
    """Bars per case: coverage and agreement, recovery time, separation and hops."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    names = list(summary)
    x = np.arange(len(names))

    def values(key: str) -> np.ndarray:
        v = np.array([np.nan if summary[n][key] is None else summary[n][key]
                      for n in names], dtype=float)
        return np.where(np.isfinite(v), v, np.nan)

    fig, axes = plt.subplots(4, 1, figsize=(max(8.0, 0.8 * len(names)), 11), sharex=True)
    width = 0.27
    for k, (key, label) in enumerate((('fraction_inside', 'inside the shape'),
                                      ('goals_claimed', 'goals claimed'),
                                      ('final_agreement', 'assignment agreement (end)'))):
        axes[0].bar(x + (k - 1) * width, values(key), width, label=label)
    axes[0].set_ylim(0, 1.05)
    axes[0].set_ylabel('share')
    axes[0].legend(loc='lower left', fontsize=8)
    axes[1].bar(x, values('recovery_time'), color='tab:purple')
    axes[1].set_ylabel('recovery time [s]\n(settle - last fault)')
    axes[2].bar(x - width / 2, values('min_separation_ratio'), width, label='whole run')
    axes[2].bar(x + width / 2, values('min_separation_after_fault'), width,
                label='after the fault')
    axes[2].axhline(1.0, color='k', lw=0.8, ls='--')
    axes[2].set_ylabel('min separation /\n(r_i + r_j)')
    axes[2].legend(loc='upper left', fontsize=8)
    axes[3].bar(x - width / 2, values('max_hops_seen'), width, label='max DSDV hops seen')
    axes[3].bar(x + width / 2, values('max_components_after_fault'), width,
                label='link-graph components')
    axes[3].plot(x, values('agents'), 'k_', ms=20, label='agents N')
    axes[3].legend(loc='upper left', fontsize=8)
    axes[3].set_xticks(x, names, rotation=30, ha='right')
    fig.suptitle(f'{title}: coverage, agreement, recovery, collisions, routing')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)




def write_json(path: pathlib.Path, payload: dict) -> None:
    """``payload`` as strict JSON (NaN and infinities as null)."""
    path.write_text(dumps(payload, indent=2), encoding='utf-8')
