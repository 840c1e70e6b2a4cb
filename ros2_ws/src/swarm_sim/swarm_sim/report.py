"""Turn a run record into metrics and figures (shared by the launcher and the evaluator)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import json
import pathlib

import numpy as np

from swarm_common.robot_types import load_robot_types
from swarm_sim import plots
from swarm_sim.metrics import SETTLE_HOLD_S, trial_metrics


def run_report(out: pathlib.Path, record: Mapping[str, np.ndarray], types: Sequence[int],
               is_beacon: Sequence[bool], shapes: Sequence, goals: Sequence,
               extra: Mapping | None = None, figures: bool = True,
               shape_times: Sequence[float] | None = None,
               settling: Mapping | None = None, separation: Mapping | None = None,
               settle_hold_s: float = SETTLE_HOLD_S) -> dict:
    """Compute every metric of a run (``swarm_sim.metrics.trial_metrics``), draw its
    figures into ``out``, return the metrics.

    ``record`` holds ``times`` (T,), ``positions``/``velocities``/``estimates`` (T, N, 2),
    ``alive``/``modes``/``goal_ids``/``digests`` (T, N). ``shapes`` are the shapes the run
    used in order; metrics are taken against the last one. With ``shape_times`` (when
    each shape was applied, on the record's clock) the shape-change metrics are added.
    ``settling`` and ``separation`` are the run's trackers' results (see trial_metrics).
    """
    out = pathlib.Path(out)
    types = np.asarray(types)
    is_beacon = np.asarray(is_beacon, dtype=bool)
    radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
    metrics: dict = dict(extra or {})
    times = np.asarray(record['times'])
    if len(times) < 2 or not shapes:
        metrics['error'] = 'run too short to measure (no truth or no shape recorded)'
        return metrics
    positions = np.nan_to_num(np.asarray(record['positions']), nan=0.0)
    shape = shapes[-1]
    metrics.update(trial_metrics(
        record, types, is_beacon, shape, radii, settling=settling, separation=separation,
        settle_hold_s=settle_hold_s,
        shapes=list(zip(shape_times, shapes)) if shape_times is not None else ()))
    metrics['real_time_factor'] = metrics.get('real_time_factor') or (
        float(times[-1] - times[0]) / metrics['wall_seconds']
        if metrics.get('wall_seconds') else None)
    if figures:
        alive = np.asarray(record['alive'])[-1]
        plots.trajectories(out / 'trajectories.png', times, np.asarray(record['positions']),
                           types, shapes, goals)
        plots.mesh(out / 'mesh.png', positions[-1][alive], types[alive], radii, shape,
                   metrics.get('epsilon_t', float('nan')),
                   metrics.get('epsilon_g', float('nan')))
        err = np.linalg.norm(np.asarray(record['estimates']) - positions, axis=2)
        err = np.where(np.asarray(record['alive']), err, np.nan)[:, ~is_beacon]
        plots.localization_error(out / 'localization_error.png', times, err)
        plots.modes(out / 'modes.png', times, np.asarray(record['modes']))
    return metrics


def summarize(trials: Sequence[Mapping]) -> dict:
    """Means over trials of every numeric metric (None/NaN ignored)."""
    mean: dict = {}
    for key in sorted({k for t in trials for k in t}):
        values = [t[key] for t in trials
                  if isinstance(t.get(key), (int, float, np.number))
                  and not isinstance(t.get(key), bool) and np.isfinite(t[key])]
        if values:
            mean[key] = float(np.mean(values))
    mean['settled_fraction'] = float(np.mean(
        [t.get('settling_time') is not None for t in trials])) if trials else 0.0
    return mean


def write_metrics(out: pathlib.Path, trials: Sequence[Mapping],
                  scenario: Mapping | None = None) -> dict:
    """Write ``out/metrics.json`` = {"scenario", "trials", "mean"}; return the means."""
    mean = summarize(trials)
    payload = {'scenario': dict(scenario or {}), 'trials': list(trials), 'mean': mean}
    (pathlib.Path(out) / 'metrics.json').write_text(dumps(payload, indent=2),
                                                     encoding='utf-8')
    return mean


def jsonable(value):
    """``value`` as strict JSON data: NaN and infinities become None, numpy scalars and
    arrays Python numbers and lists, mapping keys strings (the one sanitizer of every
    JSON file the project writes; ``dumps`` adds ``str`` for anything else)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return None if not np.isfinite(value) else float(value)
    return value


def dumps(value, **kwargs) -> str:
    """``json.dumps`` of ``jsonable(value)``; what JSON cannot hold is written as text."""
    return json.dumps(jsonable(value), default=str, **kwargs)
