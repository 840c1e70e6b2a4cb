"""The generalization study: the thesis scenario on procedural shapes nobody tuned for.

Each trial runs one shape of ``swarm_mission.shape_gen`` with one method in the headless
swarm (``swarm_sim.headless``: the thesis scenario of chapter 4 by default, 50 agents, 8
beacons, types 20/20/10) and becomes one row: settled and held (eq. 4.1), settling over
least settling time, displacement over its lower bound, eps_t, eps_g, minimum
separation, contacts, maximum localization error and assignment agreement, all read
from ``swarm_sim.metrics`` keys (a key a run does not report shows as ``-``). A shape
the swarm cannot cover (``swarm_mission.coverability``) is a row with the reason; a
trial that raises is a row with the error; none is dropped.

Every trial carries a diagnosis (``diagnose``): every agent not settled at the end
(mode, inside or not, speed, distance to its goal, its localization error, the beacons
in radio range and line of sight of it and of its goal); how many final goals have
fewer than three beacons in reach (no trilateration there, thesis 3.1.4); when and
where the worst localization error occurred (beacons in reach, their bearing spread,
time spent without a fix before); the agent that settled last (its path against the
straight line, time without a fix, goal changes); and where the displacement beyond
the straight lines went (path driven without a fix, the longest detours).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import math
import traceback

import numpy as np
import shapely
from shapely.geometry import LineString

from swarm_agent.localization import Mode
from swarm_common.goals import PartitionError
from swarm_common.robot_types import load_robot_types
from swarm_common.shapes import Shape, ShapeError
from swarm_mission.coverability import coverability_problem
from swarm_sim.headless import HeadlessSwarm, Scenario, TrialRecord
from swarm_sim.medium import MediumConfig
from swarm_sim.metrics import inside_mask, SETTLE_SPEED

METHODS = ('bubble', 'fractal', 'forces')
THESIS_TYPES = {1: 20, 2: 20, 3: 10}
TRILATERATION_BEACONS = 3     # beacons a fix needs (thesis 3.1.4)
# (header, metric key or a function of the row's metrics, digits)
COLUMNS = (
    ('settled (held)', 'settled', None),
    ('settling / least', 'settling_ratio', 2),
    ('displacement / bound', 'displacement_ratio', 3),
    ('eps_t', 'epsilon_t', 2),
    ('eps_g', 'epsilon_g', 3),
    ('min separation', 'min_separation_ratio', 2),
    ('contacts', 'contacts', None),
    ('max loc. error [m]', 'max_localization_error', 2),
    ('agreement', 'assignment_agreement', 3),
)


@dataclass(frozen=True)
class StudyTrial:
    """One shape, one method, one fleet seed."""

    shape: Shape
    kind: str
    method: str
    seed: int = 0
    type_counts: Mapping[int, int] = field(default_factory=lambda: dict(THESIS_TYPES))
    n_beacons: int = 8
    duration_s: float = 600.0


def _number(value) -> float | None:
    if isinstance(value, (bool, np.bool_)) or value is None:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _ratio(metrics: Mapping, num: str, den: str) -> float | None:
    a, b = _number(metrics.get(num)), _number(metrics.get(den))
    return a / b if a is not None and b else None


def row_metrics(metrics: Mapping) -> dict:
    """The table's quantities from a trial's metrics (``None`` where not reported)."""
    settling = _number(metrics.get('settling_ratio'))
    if settling is None:
        settling = _ratio(metrics, 'settling_time', 'least_settling_time')
    settled = metrics.get('settled')
    return {
        'settled': None if settled is None else bool(settled),
        'settling_ratio': settling,
        'displacement_ratio': _ratio(metrics, 'total_displacement',
                                     'displacement_lower_bound'),
        **{key: _number(metrics.get(key)) for key in (
            'epsilon_t', 'epsilon_g', 'max_localization_error', 'assignment_agreement')},
        # inf: no two robots ever came within reach of each other
        'min_separation_ratio': (math.inf if metrics.get('min_separation_ratio') == math.inf
                                 else _number(metrics.get('min_separation_ratio'))),
        'contacts': None if metrics.get('contacts') is None else int(metrics['contacts']),
    }


def _beacons_in_reach(point: np.ndarray, beacons: np.ndarray, range_m: float,
                      blocked) -> np.ndarray:
    """The beacons within radio range and, with obstacles, line of sight of ``point``."""
    near = beacons[np.linalg.norm(beacons - point, axis=1) <= range_m]
    near = near[~np.all(np.isclose(near, point), axis=1)] if len(near) else near
    if blocked is None or not len(near):
        return near
    return near[[not blocked.intersects(LineString([point, b])) for b in near]]


def bearing_spread(point: np.ndarray, beacons: np.ndarray) -> float | None:
    """The smallest angle (degrees) of a sector from ``point`` holding every beacon:
    near 0 the beacons stand in one direction and a fix is poor across it."""
    if len(beacons) < 2:
        return None
    angles = np.sort(np.degrees(np.arctan2(*(beacons - point).T[::-1])) % 360.0)
    gaps = np.diff(np.append(angles, angles[0] + 360.0))
    return float(360.0 - gaps.max())


def _mode_name(mode) -> str:
    return Mode(int(mode)).name if mode >= 0 else 'none'


def _worst_localization(record: TrialRecord, range_m: float, blocked) -> dict | None:
    """When and where the largest error after an agent's first fix occurred, and why:
    the beacons it could range then, their bearing spread, and how long before it had
    been without a fix (LOST or RETURN_HOME, thesis 3.1.3)."""
    pos, alive, modes, beacons = record.positions, record.alive, record.modes, \
        np.asarray(record.beacons, dtype=bool)
    err = np.linalg.norm(record.estimates - pos, axis=2)
    masked = np.where(alive & ~beacons[None, :] & np.isfinite(err), err, -1.0)
    localized = getattr(record, 'localized', None)
    first_fix = None
    if localized is not None and np.shape(localized) == masked.shape:
        fixed = np.logical_or.accumulate(np.asarray(localized, bool), axis=0)
        masked = np.where(fixed, masked, -1.0)
        first_fix = fixed
    if not masked.size or masked.max() < 0:
        return None
    k, i = np.unravel_index(int(np.argmax(masked)), masked.shape)
    reach = _beacons_in_reach(pos[k, i], pos[k][beacons & alive[k]], range_m, blocked)
    times = record.times
    window = (times > times[k] - 60.0) & (times <= times[k])
    dt = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    return {'agent': int(i), 'time': float(times[k]), 'error': float(masked[k, i]),
            'mode': _mode_name(modes[k, i]), 'beacons_in_reach': len(reach),
            'bearing_spread_deg': bearing_spread(pos[k, i], reach),
            'seconds_without_fix_in_last_60s': float(
                np.count_nonzero(modes[window, i] > 0) * dt),
            'first_fix_time': (float(times[np.argmax(first_fix[:, i])])
                               if first_fix is not None and first_fix[:, i].any() else None)}


def _detours(record: TrialRecord, limit: int = 3) -> dict:
    """Where the displacement beyond the straight lines went: path driven while not
    localized (LOST or RETURN_HOME, which heads for the shape's centre) and the agents
    with the longest detours (path length over the start-to-final straight line)."""
    pos, alive, modes = record.positions, record.alive, record.modes
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=2) * alive[1:]
    path = steps.sum(axis=0)
    straight = np.linalg.norm(pos[-1] - pos[0], axis=1)
    detour = path - straight
    order = np.argsort(-detour)[:limit]
    unfixed = (modes > 0).any(axis=0)
    return {'path_m': float(path.sum()), 'straight_m': float(straight.sum()),
            'path_without_fix_m': float(steps[modes[:-1] > 0].sum()),
            'detour_m': float(detour.sum()),
            'detour_of_agents_ever_without_fix_m': float(detour[unfixed].sum()),
            'agents_ever_without_fix': int(unfixed.sum()),
            'longest_detours': [{'agent': int(i), 'type': int(record.types[i]),
                                 'path_m': float(path[i]), 'straight_m': float(straight[i]),
                                 'seconds_without_fix': float(np.count_nonzero(
                                     modes[:, i] > 0) * np.median(np.diff(record.times)))}
                                for i in order]}


def _last_to_settle(record: TrialRecord, shape: Shape) -> dict | None:
    """The agent whose arrival fixed the settling time: the last one to enter (and
    stay in) the settled condition of eq. 4.1, with what it did on the way."""
    ok = inside_mask(shape, record.positions) & (
        np.linalg.norm(record.velocities, axis=2) < SETTLE_SPEED)
    ok |= ~record.alive
    if not ok[-1].all():
        return None
    bad = ~ok
    last_bad = np.array([np.flatnonzero(bad[:, i])[-1] if bad[:, i].any() else -1
                         for i in range(ok.shape[1])])
    i = int(np.argmax(last_bad))
    if last_bad[i] < 0:
        return None
    k = last_bad[i] + 1
    pos, modes = record.positions[:k + 1, i], record.modes[:k + 1, i]
    dt = float(np.median(np.diff(record.times)))
    return {'agent': i, 'type': int(record.types[i]), 'time': float(record.times[k]),
            'beacon': bool(record.beacons[i]),
            'path_m': float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()),
            'straight_m': float(np.linalg.norm(pos[-1] - pos[0])),
            'seconds_without_fix': float(np.count_nonzero(modes > 0) * dt),
            'goal_changes': int(np.count_nonzero(np.diff(record.goal_ids[:k + 1, i])))}


def diagnose(record: TrialRecord, shape: Shape, range_m: float | None = None) -> dict:
    """What limited a run: see the module docstring. Agent k is fleet row k."""
    range_m = MediumConfig().range_m if range_m is None else range_m
    blocked = shapely.union_all(list(shape.obstacles)) if shape.obstacles else None
    pos, vel, alive = record.positions, record.velocities, record.alive
    est, modes, goal_ids = record.estimates, record.modes, record.goal_ids
    beacons = np.asarray(record.beacons, dtype=bool)
    types = np.asarray(record.types)
    final_beacons = pos[-1][beacons & alive[-1]]
    goals = {g.id: np.array([g.x, g.y]) for g in record.goals}
    inside = inside_mask(shape, pos[-1])
    speed = np.linalg.norm(vel[-1], axis=1)
    err = np.linalg.norm(est - pos, axis=2)
    unsettled = []
    for i in np.flatnonzero(alive[-1] & ~(inside & (speed < SETTLE_SPEED))):
        goal = goals.get(int(goal_ids[-1, i]))
        unsettled.append({
            'agent': int(i), 'type': int(types[i]), 'beacon': bool(beacons[i]),
            'mode': _mode_name(modes[-1, i]),
            'mode_changes': int(np.count_nonzero(np.diff(modes[:, i][alive[:, i]]))),
            'inside': bool(inside[i]), 'speed': float(speed[i]),
            'goal_distance': None if goal is None else float(np.linalg.norm(pos[-1, i] - goal)),
            'localization_error': _number(err[-1, i]),
            'beacons_in_reach': len(_beacons_in_reach(pos[-1, i], final_beacons, range_m,
                                                      blocked)),
            'beacons_in_reach_of_goal': None if goal is None else len(_beacons_in_reach(
                goal, final_beacons, range_m, blocked)),
        })
    short = [g for g, xy in goals.items() if len(_beacons_in_reach(
        xy, final_beacons, range_m, blocked)) < TRILATERATION_BEACONS]
    return {'unsettled_agents': unsettled, 'goals_short_of_beacons': len(short),
            'goals': len(goals),
            'worst_localization': _worst_localization(record, range_m, blocked),
            'last_to_settle': _last_to_settle(record, shape),
            'detours': _detours(record),
            'fraction_settled_at_end': float(np.mean((inside & (speed < SETTLE_SPEED))[
                alive[-1]])) if alive[-1].any() else 0.0}


def _row(trial: StudyTrial, status: str, note: str = '', metrics: Mapping | None = None,
         diagnosis: Mapping | None = None) -> dict:
    return {'shape': trial.shape.name, 'kind': trial.kind, 'method': trial.method,
            'seed': trial.seed, 'area': trial.shape.area, 'status': status, 'note': note,
            **row_metrics(metrics or {}), 'metrics': dict(metrics or {}),
            'diagnosis': dict(diagnosis or {})}


def _note(diagnosis: Mapping, limit: int = 3) -> str:
    """One line naming the agents that did not settle."""
    agents = diagnosis.get('unsettled_agents') or []
    parts = []
    for a in agents[:limit]:
        where = 'inside' if a['inside'] else 'outside'
        goal = '' if a['goal_distance'] is None else f', {a["goal_distance"]:.1f} m from goal'
        reach = a['beacons_in_reach_of_goal']
        reach = '' if reach is None else f', {reach} beacons reach its goal'
        parts.append(f'agent {a["agent"]} (type {a["type"]}, {a["mode"]}, {where}, '
                     f'{a["speed"]:.2f} m/s{goal}{reach})')
    more = f' and {len(agents) - limit} more' if len(agents) > limit else ''
    short = diagnosis.get('goals_short_of_beacons')
    tail = f'; {short} of {diagnosis.get("goals")} goals reach < 3 beacons' if short else ''
    return f'{len(agents)} not settled at the end: ' + '; '.join(parts) + more + tail


def run_trial(trial: StudyTrial) -> dict:
    """One row: refused (with the reason), error (with the exception), or the metrics."""
    radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
    problem = coverability_problem(trial.shape, trial.type_counts, radii)
    if problem:
        return _row(trial, 'refused', problem)
    scenario = Scenario(shape=trial.shape, method=trial.method,
                        type_counts=dict(trial.type_counts), n_beacons=trial.n_beacons,
                        seed=trial.seed, duration_s=trial.duration_s)
    try:
        record = HeadlessSwarm(scenario).run()
    except (ShapeError, PartitionError) as exc:   # the mission refused the shape
        return _row(trial, 'refused', str(exc))
    except Exception as exc:   # a failing trial is a row, never a lost shape
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f'{last.filename.rsplit("/", 1)[-1]}:{last.lineno}'
        return _row(trial, 'error', f'{type(exc).__name__}: {exc} ({where})')
    metrics = record.metrics
    diagnosis = diagnose(record, trial.shape)
    settled = metrics.get('settled')
    if settled is None:
        settled = metrics.get('settling_time') is not None
    status = 'settled' if settled else 'not settled'
    return _row(trial, status, '' if settled else _note(diagnosis), metrics, diagnosis)


def row_from_metrics(shape: Shape, kind: str, method: str, seed: int, status: str,
                     metrics: Mapping, note: str = '') -> dict:
    """A row from a run's metrics.json trial (the ROS launcher's runs)."""
    return _row(StudyTrial(shape, kind, method, seed), status, note, metrics)


def _cell(value, digits: int | None) -> str:
    if value is None:
        return '-'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if digits is None:
        return str(int(value)) if isinstance(value, (int, float)) else str(value)
    return f'{value:.{digits}f}'


def markdown_table(rows: Sequence[Mapping]) -> str:
    """One line per row: shape, method, status, the COLUMNS and the note."""
    header = ['shape', 'method', 'status', *[c[0] for c in COLUMNS], 'note']
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    for row in rows:
        cells = [row['shape'], row['method'], row['status'],
                 *[_cell(row.get(key), digits) for _, key, digits in COLUMNS],
                 str(row.get('note', '')).replace('|', '/')]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines) + '\n'


def summary(rows: Sequence[Mapping]) -> dict:
    """Per method: settled count, median and worst ratios, worst separation and errors."""
    out: dict[str, dict] = {}
    for method in dict.fromkeys(r['method'] for r in rows):
        mine = [r for r in rows if r['method'] == method]

        def values(key: str, mine=mine) -> list[float]:
            return [r[key] for r in mine if r.get(key) is not None]

        disp, settle = values('displacement_ratio'), values('settling_ratio')
        sep, loc = values('min_separation_ratio'), values('max_localization_error')
        out[method] = {
            'trials': len(mine),
            'settled': sum(r['status'] == 'settled' for r in mine),
            'not_settled': [r['shape'] for r in mine if r['status'] == 'not settled'],
            'refused': [r['shape'] for r in mine if r['status'] == 'refused'],
            'errors': [r['shape'] for r in mine if r['status'] == 'error'],
            'median_displacement_ratio': float(np.median(disp)) if disp else None,
            'worst_displacement_ratio': max(disp) if disp else None,
            'median_settling_ratio': float(np.median(settle)) if settle else None,
            'min_separation_ratio': min(sep) if sep else None,
            'contacts': sum(values('contacts')) if values('contacts') else None,
            'worst_localization_error': max(loc) if loc else None,
        }
    return out


def summary_table(summ: Mapping[str, Mapping]) -> str:
    """The per-method summary as markdown."""
    def f(v, d):
        return '-' if v is None else f'{v:.{d}f}'

    lines = ['| method | settled | median disp. / bound | worst disp. / bound | '
             'median settling / least | min separation | contacts | worst loc. error [m] |',
             '|---|---|---|---|---|---|---|---|']
    for method, s in summ.items():
        lines.append(f'| {method} | {s["settled"]} / {s["trials"]} | '
                     f'{f(s["median_displacement_ratio"], 3)} | '
                     f'{f(s["worst_displacement_ratio"], 3)} | '
                     f'{f(s["median_settling_ratio"], 2)} | {f(s["min_separation_ratio"], 2)} | '
                     f'{"-" if s["contacts"] is None else int(s["contacts"])} | '
                     f'{f(s["worst_localization_error"], 2)} |')
    return '\n'.join(lines) + '\n'
