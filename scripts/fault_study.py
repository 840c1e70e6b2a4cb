#!/usr/bin/env python3
"""Fault-injection study of the headless swarm (issue 10): what survives which fault.

Runs the headless evaluator (``swarm_sim.headless``, the same brains, radio medium and
mission as the ROS system; scenarios built by ``scripts/evaluate.py``) under these
faults, each over ``--seeds`` seeds:

  loss_P        radio packet loss P % (0, 10, 20, 30, 50) from the start
  kill_P        P % (10, 30) of the agents killed at random times in the fault window
  beacons_one   one beacon removed at the fault time
  beacons_half  half of the beacons removed at the fault time
  range_R       radio range cut from 25 m to R m at the fault time (down to a partition)
  obstacle      a radio-opaque wall sweeping through the formation (links cut, not bodies)

and reports per trial: coverage (``fraction_inside``, share of the final goals claimed by
a living agent, share with an agent of their type truly within ``GOAL_TOLERANCE_M``,
epsilon_t/epsilon_g), agreement of the
surviving agents (``assignment_agreement`` over the run and after the fault, at the end,
``duplicate_goal_claims_final`` and ``_peak``), recovery time (settling time, eq. 4.1 with
its hold window, minus the last fault time), collisions (``min_separation_ratio`` over every
simulation step of the run and after the fault, ``contacts``), and DSDV
health sampled every 2 s from the brains' route tables: the largest finite hop count
seen (count-to-infinity would push it to the network size or beyond), next-hop loops,
finite routes to dead agents, and the true link graph's connected components.

Writes into --out: ``faults.json`` (config, every trial, per-case means), ``faults.md``
(markdown table) and ``faults.png`` (bars per case).

Example (default: 20 agents, 4 beacons, circle_314, +/-25 m, 2 seeds, about 5 min on
2 cores):
  scripts/env.sh python scripts/fault_study.py --out results/faults
  scripts/env.sh python scripts/fault_study.py --out /tmp/faults --quick
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import json
import math
import pathlib
import sys
from typing import Any

import evaluate
import numpy as np
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from swarm_agent.wire import INFINITE_HOPS
from swarm_mission.partition import PartitionError
from swarm_mission.robot_types import RobotTypeError
from swarm_mission.shapes import ShapeError
from swarm_sim.headless import HeadlessSwarm, Scenario, ScenarioError, TrialRecord
from swarm_sim.medium import MediumConfig, RadioMedium, SweepingWall
from swarm_sim.metrics import agreement_by_sample

GOAL_TOLERANCE_M = 1.5      # a goal counts as covered by an agent of its type this close
SAMPLE_EVERY = 4            # route tables sampled every 4th record frame (2 s)
LOSSES = (0, 10, 20, 30, 50)
KILLS = (10, 30)
RANGES = (12.0, 8.0, 5.0, 3.0)
MEAN_KEYS = ('fraction_inside', 'goals_claimed', 'goals_reached', 'epsilon_t', 'epsilon_g',
             'assignment_agreement', 'agreement_after_fault', 'final_agreement',
             'duplicate_goal_claims_final', 'duplicate_goal_claims_peak', 'settling_time',
             'recovery_time', 'settled', 'min_separation_ratio', 'min_separation_after_fault',
             'contacts', 'max_hops_seen',
             'routing_loops', 'stale_routes_to_dead', 'max_components_after_fault',
             'beacons_alive', 'min_beacons_heard', 'final_modes_normal', 'passed',
             'duration', 'wall_seconds')


# ---------------------------------------------------------------------------- cases
QUICK_CASES = ('loss_0', 'loss_30', 'kill_30', 'beacons_one', 'range_2', 'obstacle')


def fault_cases(ranges: tuple[float, ...] = RANGES) -> list[dict[str, Any]]:
    """The fault cases of the study, in table order."""
    cases: list[dict[str, Any]] = [{'name': f'loss_{p}', 'kind': 'loss', 'value': p / 100.0}
                                   for p in LOSSES]
    cases += [{'name': f'kill_{p}', 'kind': 'kill', 'value': p / 100.0} for p in KILLS]
    cases.append({'name': 'beacons_one', 'kind': 'beacons', 'value': 1})
    cases.append({'name': 'beacons_half', 'kind': 'beacons', 'value': 0.5})
    cases += [{'name': f'range_{r:g}', 'kind': 'range', 'value': float(r)} for r in ranges]
    cases.append({'name': 'obstacle', 'kind': 'obstacle', 'value': 0.0})
    return cases


def _components(swarm: HeadlessSwarm) -> int:
    """Connected components of the true radio link graph among the living agents."""
    return link_components(swarm.medium, {swarm.ids[i] for i in np.flatnonzero(swarm.alive)})


def link_components(medium: RadioMedium, alive: set[int]) -> int:
    """Connected components of the medium's link graph among the ``alive`` agent ids."""
    ids, links = medium.adjacency()
    keep = [k for k, a in enumerate(ids) if a in alive]
    if not keep:
        return 0
    return int(connected_components(links[np.ix_(keep, keep)], directed=False)[0])


class RouteMonitor:
    """Samples DSDV health of every living brain (the ``progress`` callback of a run)."""

    def __init__(self, swarm: HeadlessSwarm, fault_time: float) -> None:
        self.swarm = swarm
        self.fault_time = fault_time
        self.calls = 0
        self.max_hops = 0
        self.max_hops_vs_size = -math.inf   # max finite hops minus (living agents - 1)
        self.loops = 0
        self.max_components_after = 0
        self.components_timeline: list[tuple[float, int]] = []

    def __call__(self, t: float, duration: float) -> None:
        """Sample every ``SAMPLE_EVERY``-th record frame."""
        self.calls += 1
        if self.calls % SAMPLE_EVERY:
            return
        self.sample(t)

    def sample(self, t: float) -> None:
        """Hop counts, next-hop loops and link-graph components now."""
        sw = self.swarm
        n_alive = int(sw.alive.sum())
        for brain in sw.brains:
            if brain is None:
                continue
            for route in brain.router.routes():
                if route.hop_count < INFINITE_HOPS:
                    self.max_hops = max(self.max_hops, route.hop_count)
                    self.max_hops_vs_size = max(self.max_hops_vs_size,
                                                route.hop_count - (n_alive - 1))
        self.loops += count_routing_loops(sw)
        comps = _components(sw)
        self.components_timeline.append((t, comps))
        if t >= self.fault_time:
            self.max_components_after = max(self.max_components_after, comps)


def count_routing_loops(swarm: HeadlessSwarm) -> int:
    """(source, destination) pairs whose next-hop chain revisits an agent."""
    return count_loops({b.router.id: {d: r.next_hop for d, r in b.router.table.items()
                                      if r.hop_count < INFINITE_HOPS}
                        for b in swarm.brains if b is not None})


def count_loops(tables: dict[int, dict[int, int]]) -> int:
    """Loops in next-hop tables: ``tables[a][d]`` is a's next hop of a finite route to d.

    Counts the (source, destination) pairs whose chain of next hops revisits an agent.
    """
    loops = 0
    for source, table in tables.items():
        for dest in table:
            seen = {source}
            current = source
            while current != dest:
                hop = tables.get(current, {}).get(dest)
                if hop is None:
                    break
                if hop in seen:
                    loops += 1
                    break
                seen.add(hop)
                current = hop
    return loops


def stale_routes_to_dead(swarm: HeadlessSwarm) -> int:
    """Finite routes held by living agents towards agents that were removed."""
    dead = {swarm.ids[i] for i in np.flatnonzero(~swarm.alive)}
    return sum(1 for b in swarm.brains if b is not None
               for r in b.router.routes() if r.destination in dead
               and r.hop_count < INFINITE_HOPS)


def min_beacons_heard(swarm: HeadlessSwarm) -> int:
    """Fewest living beacons a living non-beacon agent has as direct radio neighbours."""
    return fewest_beacons_heard(swarm.medium, swarm.ids, swarm.alive, swarm.is_beacon)


def fewest_beacons_heard(medium: RadioMedium, ids, alive: np.ndarray,
                         is_beacon: np.ndarray) -> int:
    """Fewest living beacons a living non-beacon has as direct neighbours in ``medium``."""
    beacons = {ids[i] for i in np.flatnonzero(is_beacon & alive)}
    counts = [len(beacons & set(medium.neighbours(ids[i])))
              for i in np.flatnonzero(alive & ~is_beacon)]
    return min(counts) if counts else len(beacons)


def critical_range(positions: np.ndarray) -> float:
    """Longest edge of the Euclidean minimum spanning tree: below it the mesh partitions."""
    if len(positions) < 2:
        return 0.0
    d = np.linalg.norm(positions[:, None] - positions[None], axis=2)
    return float(minimum_spanning_tree(d).toarray().max())


# ---------------------------------------------------------------------------- faults
def fault_plan(case: dict, config: dict, seed: int, ids: list[int], beacon_ids: list[int],
               half_size: float) -> dict[str, Any]:
    """What the case does and when, for the headless swarm and the ROS launcher alike.

    ``removals``: [(time, [agent ids])]; ``settings``: [(time, name, value)] with the
    names of ``swarm_sim.medium.RUNTIME_SETTINGS`` (sim_node's run-time parameters);
    ``first``/``last``: time of the first fault and of the end of the last one.
    """
    kind, value = case['kind'], case['value']
    t_fault = float(config['fault_time'])
    rng = np.random.default_rng([seed, 10_007])
    plan: dict[str, Any] = {'removals': [], 'settings': [], 'first': t_fault, 'last': t_fault}
    if kind == 'loss':
        plan.update(settings=[(0.0, 'loss', value)], first=0.0, last=0.0)
    elif kind == 'kill':
        count = max(1, int(round(value * len(ids))))
        victims = rng.choice(ids, size=count, replace=False)
        times = np.sort(rng.uniform(t_fault, t_fault + config['fault_window'], size=count))
        plan.update(removals=[(float(t), [int(a)]) for t, a in zip(times, victims)],
                    first=float(times[0]), last=float(times[-1]))
    elif kind == 'beacons':
        count = int(value) if value >= 1 else int(math.ceil(value * len(beacon_ids)))
        victims = rng.choice(beacon_ids, size=count, replace=False) if count else []
        plan['removals'] = [(t_fault, [int(a) for a in victims])]
    elif kind == 'range':
        plan['settings'] = [(t_fault, 'radio_range_m', float(value))]
    elif kind == 'obstacle':
        # A wall as long as the workspace sweeps across it at wall_speed, then vanishes.
        speed = float(config['wall_speed'])
        plan.update(settings=[(t_fault, 'radio_wall_speed_mps', speed)],
                    last=t_fault + 2.0 * half_size / speed)
    else:
        raise ScenarioError(f'unknown fault kind {kind!r}')
    return plan


def apply_setting(medium: RadioMedium, name: str, value: float, t: float,
                  half_size: float) -> None:
    """One run-time setting of the medium, as sim_node applies its parameter."""
    if name == 'loss':
        medium.set_loss(value)
    elif name == 'radio_range_m':
        medium.set_range(value)
    elif name == 'radio_wall_speed_mps':
        medium.start_wall(SweepingWall(t, value, half_size) if value > 0 else None)
    else:
        raise ScenarioError(f'unknown medium setting {name!r}')


def _setting_event(name: str, value: float):
    def apply(swarm: HeadlessSwarm, t: float) -> None:
        apply_setting(swarm.medium, name, value, t, swarm.scenario.half_size)
        swarm.mission.events.append(f't={t:.1f} s: {name} = {value:g}')
    return apply


def _move_wall(swarm: HeadlessSwarm, t: float) -> None:
    swarm.medium.move_wall(t)


def configure_fault(swarm: HeadlessSwarm, case: dict, config: dict, seed: int
                    ) -> tuple[float, float]:
    """Schedule the case's fault and its observation window; return (first, last) time."""
    sc = swarm.scenario
    plan = fault_plan(case, config, seed, list(swarm.ids),
                      [swarm.ids[i] for i in np.flatnonzero(swarm.is_beacon)], sc.half_size)
    sc.removals = plan['removals']
    events = []
    for t, name, value in plan['settings']:
        if t <= 0.0:
            apply_setting(swarm.medium, name, value, 0.0, sc.half_size)
        else:
            events.append((t, _setting_event(name, value)))
        if name == 'radio_wall_speed_mps':
            # sim_node moves the wall with every link update; here every record period
            steps = int((plan['last'] - t) / sc.record_period_s) + 1
            events += [(t + k * sc.record_period_s, _move_wall) for k in range(steps + 1)]
    if case['kind'] != 'loss':
        # A swarm settled through the fault would otherwise stop one hold window after
        # it, before a lost beacon or a shorter range has shown its effect on
        # localization. Not an event: an event is a change, and restarts the hold.
        sc.min_duration_s = plan['last'] + config['observe']
    sc.events = events
    return plan['first'], plan['last']


# ---------------------------------------------------------------------------- trial
def build_swarm(case: dict, config: dict, seed: int) -> HeadlessSwarm:
    """The case's swarm, built by evaluate.build_scenario with the study's settings."""
    argv = ['--out', '-', '--agents', str(config['agents']), '--beacons',
            str(config['beacons']), '--shape', config['shape'], '--shape-scale',
            str(config['shape_scale']), '--duration', str(config['duration']),
            '--method', config['method']]
    scenario: Scenario = evaluate.build_scenario(evaluate.parse_args(argv), seed)
    scenario.half_size = config['half_size']
    return HeadlessSwarm(scenario)


def _agreement(record: TrialRecord, frames: np.ndarray) -> float:
    """Mean over ``frames`` of ``swarm_sim.metrics.agreement_by_sample`` (NaN: none after
    the first complete consensus round)."""
    shares = agreement_by_sample(record.alive, record.digests, record.types)[frames]
    shares = shares[np.isfinite(shares)]
    return float(np.mean(shares)) if len(shares) else float('nan')


def goals_claimed(record: TrialRecord) -> float:
    """Share of the final goals that some living agent holds as its goal (its belief)."""
    if not record.goals:
        return float('nan')
    claimed = set(record.goal_ids[-1][record.alive[-1]].tolist())
    return sum(g.id in claimed for g in record.goals) / len(record.goals)


def goals_reached(record: TrialRecord) -> float:
    """Share of the final goals with a living agent of their type within the tolerance."""
    if not record.goals:
        return float('nan')
    final = record.positions[-1]
    alive = record.alive[-1]
    covered = 0
    for goal in record.goals:
        mine = alive & (record.types == goal.type)
        if mine.any():
            d = np.linalg.norm(final[mine] - np.array([goal.x, goal.y]), axis=1)
            covered += bool(d.min() <= GOAL_TOLERANCE_M)
    return covered / len(record.goals)


def coverage_columns(record, metrics: dict, first: float, last: float,
                     separation: tuple[np.ndarray, np.ndarray] | None) -> dict[str, Any]:
    """Columns computed from a record of truth and belief (headless or ROS), same keys.

    ``record`` has times, positions, velocities, alive, modes, digests, goal_ids, types
    and goals (the final goals: id, type, x, y); ``metrics`` the run's trial metrics
    (``settling_time`` with its hold window); ``separation`` the simulator's (times,
    smallest separation ratio of the steps up to each time), None if it has none.
    """
    after = np.flatnonzero(record.times >= first)
    if len(after) == 0:
        after = np.array([len(record.times) - 1])
    alive_now = record.alive[-1]
    settle = metrics.get('settling_time')
    sep_after = None
    if separation is not None and np.any(separation[0] >= first):
        sep_after = float(np.min(separation[1][separation[0] >= first]))
    return {
        'fault_time': first, 'last_fault_time': last,
        'agents': len(record.types), 'agents_alive': int(alive_now.sum()),
        'goals_claimed': goals_claimed(record), 'goals_reached': goals_reached(record),
        'agreement_after_fault': _agreement(record, after),
        'final_agreement': _agreement(record, np.array([len(record.times) - 1])),
        'settling_time': settle, 'settled': settle is not None,
        'recovery_time': None if settle is None else max(0.0, settle - last),
        'min_separation_after_fault': sep_after,
        'critical_range_at_fault': critical_range(
            record.positions[after[0]][record.alive[after[0]]]),
        'critical_range_final': critical_range(record.positions[-1][alive_now]),
    }


def judge(row: dict[str, Any]) -> dict[str, Any]:
    """The issue's target and the pass verdict of a row (see the docs' columns)."""
    # The target: nothing lost, coverage restored, while >= 3 beacons reachable.
    row['target_applies'] = row['beacons_alive'] >= 3 and row['min_beacons_heard'] >= 3
    # Nothing lost: settled inside the shape, every goal claimed by exactly one living
    # agent. Identical digests (same cost rows) are reported but not required: under
    # loss agents may hold different row sets and still compute the same assignment.
    # goals_reached (true distance) is reported too; it is bounded by localization.
    row['passed'] = bool(row['settled'] and row['fraction_inside'] >= 1.0
                         and row['goals_claimed'] >= 1.0
                         and row['duplicate_goal_claims_final'] == 0
                         and not row['count_to_infinity'] and row['routing_loops'] == 0
                         and not row.get('crashed'))
    return row


def run_case(case: dict, config: dict, seed: int) -> dict[str, Any]:
    """Run one (case, seed) trial and return its row of the study."""
    swarm = build_swarm(case, config, seed)
    first, last = configure_fault(swarm, case, config, seed)
    monitor = RouteMonitor(swarm, first)
    record = swarm.run(progress=monitor)
    monitor.sample(float(record.times[-1]))
    m = record.metrics
    beacons_alive = int((swarm.is_beacon & swarm.alive).sum())
    row: dict[str, Any] = {
        'case': case['name'], 'kind': case['kind'], 'value': case['value'], 'seed': seed,
        **coverage_columns(record, m, first, last, (record.times, record.min_separation)),
        'fraction_inside': m['fraction_inside'],
        'epsilon_t': m['epsilon_t'], 'epsilon_g': m['epsilon_g'],
        'assignment_agreement': m['assignment_agreement'],
        'duplicate_goal_claims_final': m['duplicate_goal_claims_final'],
        'duplicate_goal_claims_peak': m['duplicate_goal_claims_peak'],
        'min_separation_ratio': m['min_separation_ratio'], 'contacts': m['contacts'],
        'max_hops_seen': monitor.max_hops,
        'count_to_infinity': bool(monitor.max_hops_vs_size > 0),
        'routing_loops': monitor.loops,
        'stale_routes_to_dead': stale_routes_to_dead(swarm),
        'max_components_after_fault': monitor.max_components_after,
        'final_components': monitor.components_timeline[-1][1],
        'beacons_alive': beacons_alive, 'min_beacons_heard': min_beacons_heard(swarm),
        'final_modes_normal': m['final_modes_normal'],
        'rms_localization_error': m['rms_localization_error'],
        'medium': m['medium'], 'events': record.events,
        'duration': m['duration'], 'wall_seconds': m['wall_seconds'],
    }
    return judge(row)


# ---------------------------------------------------------------------------- report
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
        out[case['name']] = summary
    return out


def _fmt(value: Any, digits: int = 2) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return 'n/a'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, int):
        return str(value)
    return f'{value:.{digits}f}'


def markdown_table(summary: dict[str, dict[str, Any]], crashes: bool = False) -> str:
    """One row per case: coverage, agreement, recovery, collisions, DSDV, target.

    ``crashes`` adds the column of runs in which a node died (ROS runs).
    """
    head = ('| Case | inside | goals claimed (reached) | eps_t | eps_g | agree (after fault) | '
            'agree (end) | dup claims | settled | recovery [s] | min sep (after fault) | '
            'max hops / N | loops | components | beacons (min heard) | '
            + ('crashed | ' if crashes else '') + 'passed |')
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



# ---------------------------------------------------------------------------- ROS
# The same cases through the full ROS system (sim_node, mission_node, composed agents),
# one launch_swarm run at a time; faults by its --remove and --set-sim.
ROOT = pathlib.Path(__file__).resolve().parent.parent
LAUNCH = ROOT / 'scripts' / 'launch_swarm.py'
ROS_CASES = ('loss_0', 'loss_20', 'loss_50', 'kill_30', 'beacons_half', 'range_2',
             'obstacle')
ROUTE_FRESH_S = 5.0     # a route table older than this (sim s) is of a dead agent
NO_ROUTE = 255          # swarm_msgs/RouteEntry.INFINITE_HOPS, also "no entry"


def _override(base: dict[str, Any], args: argparse.Namespace, keys: tuple[str, ...]) -> None:
    """The arguments given explicitly (not None) replace the defaults in ``base``."""
    for key in keys:
        if getattr(args, key) is not None:
            base[key] = getattr(args, key)
    if args.ranges is not None:
        base['ranges'] = tuple(args.ranges)


def ros_config(args: argparse.Namespace) -> dict[str, Any]:
    """Defaults of the ROS study (the e2e test's 12-agent square), overridden by args."""
    base = {'agents': 12, 'beacons': 4, 'seeds': 1, 'half_size': 15.0, 'fault_time': 80.0,
            'duration': 240.0, 'observe': 60.0, 'ranges': (2.0,), 'wall_speed': 1.0,
            'shape': str(ROOT / 'tests' / 'data' / 'square_8m.json'), 'settle_hold': 3.0,
            'timeout': 1200.0}
    _override(base, args, ('agents', 'beacons', 'seeds', 'half_size', 'fault_time',
                           'duration', 'observe', 'shape'))
    base.update(method=args.method, fault_window=args.fault_window, seed=args.seed,
                ros=True, composed=True)
    return base


def ros_launch_argv(case: dict, config: dict, seed: int, run_dir: pathlib.Path
                    ) -> tuple[list[str], dict[str, Any]]:
    """launch_swarm.py arguments of a (case, seed) run and the case's fault plan."""
    import launch_swarm

    argv = ['--agents', str(config['agents']), '--beacons', str(config['beacons']),
            '--method', config['method'], '--shape', str(config['shape']),
            '--half-size', f'{config["half_size"]:g}', '--duration', f'{config["duration"]:g}',
            '--settle-hold', f'{config["settle_hold"]:g}', '--composed', '--seed', str(seed),
            '--out', str(run_dir)]
    try:
        _, _, _, fleet = launch_swarm.validate(launch_swarm.parse_args(argv))
    except launch_swarm.LaunchError as exc:
        raise ScenarioError(f'launch_swarm refuses the scenario: {exc}') from None
    robots = sorted(fleet, key=lambda r: r.id)
    plan = fault_plan(case, config, seed, [r.id for r in robots],
                      [r.id for r in robots if r.is_beacon], config['half_size'])
    for t, victims in plan['removals']:
        argv += ['--remove', f'{t:.2f}:' + ','.join(str(v) for v in victims)]
    for t, name, value in plan['settings']:
        argv += ['--set-sim', f'{t:g}:{name}={value:g}']
    if case['kind'] != 'loss':
        until = min(config['duration'], plan['last'] + config['observe'])
        argv += ['--min-duration', f'{until:g}']
    return argv, plan


def run_ros_case(case: dict, config: dict, seed: int, out: pathlib.Path) -> dict[str, Any]:
    """One launch_swarm run of the case (its output in out/CASE_sSEED/), and its row."""
    import shutil
    import signal
    import subprocess
    import time

    run_dir = out / f'{case["name"]}_s{seed}'
    if run_dir.exists():
        shutil.rmtree(run_dir)
    argv, plan = ros_launch_argv(case, config, seed, run_dir)
    run_dir.mkdir(parents=True)
    (run_dir / 'command.txt').write_text(' '.join(['scripts/launch_swarm.py', *argv]) + '\n',
                                         encoding='utf-8')
    wall0 = time.monotonic()
    with open(run_dir / 'launcher.log', 'w', encoding='utf-8') as log:
        proc = subprocess.Popen([sys.executable, str(LAUNCH), *argv], stdout=log,
                                stderr=subprocess.STDOUT, cwd=str(ROOT))
        try:
            returncode = proc.wait(timeout=config['timeout'])
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)   # the launcher stops its children itself
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            returncode = None
    return ros_row(case, config, seed, run_dir, plan, returncode, time.monotonic() - wall0)


def _crashed_nodes(run_dir: pathlib.Path, metrics: dict) -> tuple[list[str], list[str]]:
    """Nodes that died during the run (the launcher's crash outcome), and node logs with a
    traceback (a crash, or an exception while the launcher stopped them at the end)."""
    crashed = []
    outcome = str(metrics.get('outcome', ''))
    if outcome.startswith('crash of '):
        crashed.append(outcome[len('crash of '):])
    tracebacks = [log.stem for log in sorted((run_dir / 'logs').glob('*.log'))
                  if 'Traceback (most recent call last)' in log.read_text(
                      encoding='utf-8', errors='replace')]
    return crashed, tracebacks


def route_columns(data, record, ids: list[int], first: float) -> dict[str, Any]:
    """DSDV health from the launcher's route samples: hops, loops, stale routes."""
    times = np.asarray(data['route_times'], dtype=float)
    max_hops, vs_size, loops, stale = 0, -math.inf, 0, 0
    for s, t in enumerate(times):
        k = min(int(np.searchsorted(record.times, t)), len(record.times) - 1)
        alive = record.alive[k]
        age = t - data['route_stamp'][s]
        fresh = alive & np.isfinite(age) & (age <= ROUTE_FRESH_S)
        hops = data['route_hops'][s]
        tables = {}
        for i in np.flatnonzero(fresh):
            finite = np.flatnonzero(hops[i] < NO_ROUTE)
            tables[ids[i]] = {ids[j]: int(data['route_next'][s][i, j]) for j in finite}
            if len(finite):
                max_hops = max(max_hops, int(hops[i, finite].max()))
                vs_size = max(vs_size, int(hops[i, finite].max()) - (int(alive.sum()) - 1))
        loops += count_loops(tables)
        if s == len(times) - 1:
            dead = ~record.alive[-1]
            stale = int(sum(np.sum((hops[i] < NO_ROUTE) & dead) for i in np.flatnonzero(fresh)))
    return {'max_hops_seen': max_hops, 'count_to_infinity': bool(vs_size > 0),
            'routing_loops': loops, 'stale_routes_to_dead': stale,
            'route_samples': len(times)}


def link_columns(record, ids: list[int], is_beacon: np.ndarray, settings: list, config: dict,
                 shape, first: float) -> dict[str, Any]:
    """Replay the medium's link graph on the recorded truth with the settings applied."""
    medium = RadioMedium(MediumConfig(), np.random.default_rng(0), list(shape.obstacles))
    pending = sorted(settings)
    components_after, final = 0, 0
    frames = list(range(0, len(record.times), SAMPLE_EVERY))
    if frames[-1] != len(record.times) - 1:
        frames.append(len(record.times) - 1)
    for k in frames:
        t = float(record.times[k])
        while pending and pending[0][0] <= t:
            when, name, value = pending.pop(0)
            apply_setting(medium, name, value, when, config['half_size'])
        medium.move_wall(t)
        living = np.flatnonzero(record.alive[k])
        medium.update_positions([ids[i] for i in living], record.positions[k][living])
        final = link_components(medium, {ids[i] for i in living})
        if t >= first:
            components_after = max(components_after, final)
    return {'max_components_after_fault': components_after, 'final_components': final,
            'min_beacons_heard': fewest_beacons_heard(medium, ids, record.alive[-1],
                                                      is_beacon)}


def ros_row(case: dict, config: dict, seed: int, run_dir: pathlib.Path, plan: dict,
            returncode: int | None, wall_seconds: float) -> dict[str, Any]:
    """The study's row of one ROS run, from its metrics.json, record.npz and logs."""
    from types import SimpleNamespace

    from swarm_mission.shapes import load_shape
    from swarm_sim.fleet import load_fleet

    row: dict[str, Any] = {'case': case['name'], 'kind': case['kind'],
                           'value': case['value'], 'seed': seed, 'ros': True,
                           'launcher_exit': returncode, 'wall_seconds': wall_seconds,
                           'run_dir': str(run_dir)}
    try:
        metrics = json.loads((run_dir / 'metrics.json').read_text())['trials'][0]
        data = np.load(run_dir / 'record.npz')
    except (OSError, ValueError, KeyError, IndexError) as exc:
        row.update(error=f'no results: {exc}', crashed=['launcher'], passed=False,
                   target_applies=False, settled=False)
        return row
    row['crashed'], row['tracebacks'] = _crashed_nodes(run_dir, metrics)
    if returncode is None:
        row['crashed'].append('timeout')
    ids = [int(a) for a in data['agent_ids']]
    fleet = {r.id: r for r in load_fleet(run_dir / 'fleet.yaml')}
    types = np.array([fleet[a].type for a in ids])
    is_beacon = np.array([fleet[a].is_beacon for a in ids], dtype=bool)
    goals = [SimpleNamespace(id=int(i), type=int(t), x=float(xy[0]), y=float(xy[1]))
             for i, t, xy in zip(data['goal_id'], data['goal_type'], data['goal_xy'])]
    record = SimpleNamespace(
        times=np.asarray(data['times'], dtype=float),
        positions=np.nan_to_num(np.asarray(data['positions'], dtype=float), nan=0.0),
        velocities=np.asarray(data['velocities'], dtype=float),
        alive=np.asarray(data['alive'], dtype=bool), modes=np.asarray(data['modes']),
        digests=np.asarray(data['digests']), goal_ids=np.asarray(data['goal_ids']),
        types=types, goals=goals)
    if len(record.times) < 2 or 'fraction_inside' not in metrics:
        row.update(error=metrics.get('error', 'run too short'), passed=False,
                   target_applies=False, settled=False)
        return row
    # Settings as the sim applied them (sent when the sim time passed the planned time).
    applied = [(float(e.get('sent_at', e['time'])), e['name'], float(e['value']))
               for e in metrics.get('sim_settings', []) if e.get('ok')]
    shape = load_shape(config['shape'])
    separation = ((np.asarray(data['separation_times'], dtype=float),
                   np.asarray(data['separation_min'], dtype=float))
                  if 'separation_times' in data else None)
    row.update(coverage_columns(record, metrics, plan['first'], plan['last'], separation))
    row.update(route_columns(data, record, ids, plan['first']))
    row.update(link_columns(record, ids, is_beacon, applied, config, shape, plan['first']))
    medium_file = run_dir / 'medium.json'
    row.update({
        'fraction_inside': metrics['fraction_inside'],
        'epsilon_t': metrics.get('epsilon_t'), 'epsilon_g': metrics.get('epsilon_g'),
        'assignment_agreement': metrics.get('assignment_agreement'),
        'duplicate_goal_claims_final': metrics.get('duplicate_goal_claims_final'),
        'duplicate_goal_claims_peak': metrics.get('duplicate_goal_claims_peak'),
        'min_separation_ratio': metrics.get('min_separation_ratio'),
        'contacts': metrics.get('contacts'),
        'beacons_alive': int((is_beacon & record.alive[-1]).sum()),
        'final_modes_normal': metrics.get('final_modes_normal'),
        'rms_localization_error': metrics.get('rms_localization_error'),
        'outcome': metrics.get('outcome'), 'sim_settings': metrics.get('sim_settings', []),
        'settings_failed': [e for e in metrics.get('sim_settings', []) if not e.get('ok')],
        'removals': plan['removals'],
        'medium': json.loads(medium_file.read_text()) if medium_file.exists() else None,
        'real_time_factor': metrics.get('real_time_factor'),
        'duration': metrics.get('duration'),
    })
    return judge(row)


def select_cases(cases: list[dict], spec: str, default: set[str] | None) -> list[dict] | None:
    """The cases named in ``spec`` (a comma list), else those in ``default`` (None: all).

    None, after a one-line error naming the known cases, when a name is unknown.
    """
    wanted = set(spec.split(',')) if spec else default
    if wanted is None:
        return cases
    unknown = wanted - {c['name'] for c in cases}
    if unknown:
        print(f'fault_study.py: unknown cases {sorted(unknown)}; known: '
              f'{[c["name"] for c in cases]}', file=sys.stderr)
        return None
    return [c for c in cases if c['name'] in wanted]


def run_ros_study(args: argparse.Namespace, argv: list[str] | None) -> int:
    """--ros: the cases through launch_swarm, one run at a time; faults_ros.*."""
    import time

    config = ros_config(args)
    cases = select_cases(fault_cases(config['ranges']), args.cases, set(ROS_CASES))
    if cases is None:
        return 2
    out = pathlib.Path(args.out)
    try:
        if config['seeds'] < 1:
            raise ScenarioError('--seeds must be at least 1')
        if config['fault_time'] >= config['duration']:
            raise ScenarioError('--fault-time must be before the end of --duration')
        ros_launch_argv(cases[0], config, config['seed'], out / 'check')
    except (ShapeError, ScenarioError, RobotTypeError, PartitionError) as exc:
        print(f'fault_study.py: {exc}', file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    seeds = [config['seed'] + k for k in range(config['seeds'])]
    rows: list[dict] = []
    wall0 = time.monotonic()
    for case in cases:
        for seed in seeds:
            row = run_ros_case(case, config, seed, out)
            rows.append(row)
            print(f'fault study (ROS): {case["name"]} seed {seed}: '
                  f'{row.get("outcome", row.get("error"))}, passed {row["passed"]}, '
                  f'{row["wall_seconds"]:.0f} s wall', flush=True)
    summary = summarise(rows, cases)
    payload = {'config': config, 'wall_seconds': time.monotonic() - wall0,
               'command': ' '.join(['scripts/fault_study.py', *(
                   argv if argv is not None else sys.argv[1:])]),
               'cases': summary, 'trials': rows}
    (out / 'faults_ros.json').write_text(json.dumps(_finite(payload), indent=2,
                                                    default=_json_default), encoding='utf-8')
    (out / 'faults_ros.md').write_text(markdown_table(summary, crashes=True),
                                       encoding='utf-8')
    plot(out / 'faults_ros.png', summary, title='Fault study through ROS')
    print(markdown_table(summary, crashes=True))
    print(f'fault study (ROS): {len(rows)} runs, {payload["wall_seconds"] / 60:.1f} min '
          f'-> {out}')
    return 0


# ---------------------------------------------------------------------------- main
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', required=True, help='results directory')
    parser.add_argument('--agents', type=int, default=None, help='swarm size (default 20)')
    parser.add_argument('--beacons', type=int, default=None, help='beacon count (default 4)')
    parser.add_argument('--seeds', type=int, default=None, help='seeds per case (default 2)')
    parser.add_argument('--seed', type=int, default=0, help='first seed')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--shape', default=None,
                        help='shape (default circle_314; with --ros tests/data/square_8m.json)')
    parser.add_argument('--shape-scale', type=float, default=None)
    parser.add_argument('--half-size', type=float, default=None,
                        help='workspace half size of the random deployment [m]')
    parser.add_argument('--method', choices=('bubble', 'fractal'), default='bubble')
    parser.add_argument('--fault-time', type=float, default=None,
                        help='time of the fault (kills: start of the window) [s]')
    parser.add_argument('--fault-window', type=float, default=30.0,
                        help='kills happen at random times in this window [s]')
    parser.add_argument('--duration', type=float, default=None, help='max simulated s')
    parser.add_argument('--observe', type=float, default=None,
                        help='never stop before this long after the last fault [s] '
                        '(default 90, quick 20)')
    parser.add_argument('--ranges', type=float, nargs='+', default=None,
                        help='reduced radio ranges [m] (default 12 8 5 3)')
    parser.add_argument('--cases', default='', help='comma-separated subset of case names')
    parser.add_argument('--quick', action='store_true',
                        help='tiny swarm and short trials (a test, seconds)')
    parser.add_argument('--ros', action='store_true',
                        help='run the cases through the full ROS system (launch_swarm, '
                        'composed agents, one run at a time; default 12 agents, 4 beacons, '
                        'the 8 m square in +/-15 m, cases ' + ','.join(ROS_CASES) + ')')
    return parser.parse_args(argv)


def study_config(args: argparse.Namespace) -> dict[str, Any]:
    """Defaults of the full study, or of --quick, overridden by explicit arguments."""
    if args.quick:
        base = {'agents': 6, 'beacons': 4, 'seeds': 1, 'shape_scale': 0.6, 'half_size': 10.0,
                'fault_time': 40.0, 'duration': 150.0, 'ranges': (2.0,), 'wall_speed': 2.0,
                'observe': 20.0}
    else:
        base = {'agents': 20, 'beacons': 4, 'seeds': 2, 'shape_scale': 1.0,
                'half_size': 25.0, 'fault_time': 120.0, 'duration': 360.0, 'ranges': RANGES,
                'wall_speed': 1.0, 'observe': 90.0}
    _override(base, args, ('agents', 'beacons', 'seeds', 'shape_scale', 'half_size',
                           'fault_time', 'duration', 'observe'))
    base.update(shape=args.shape or 'circle_314', method=args.method,
                fault_window=args.fault_window, seed=args.seed, workers=args.workers,
                quick=args.quick)
    if args.quick:
        base['fault_window'] = min(base['fault_window'], 10.0)
    return base


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.ros:
        return run_ros_study(args, argv)
    config = study_config(args)
    cases = select_cases(fault_cases(config['ranges']), args.cases,
                         set(QUICK_CASES) if args.quick else None)
    if cases is None:
        return 2
    try:
        if config['seeds'] < 1 or config['workers'] < 1:
            raise ScenarioError('--seeds and --workers must be at least 1')
        if config['fault_time'] >= config['duration']:
            raise ScenarioError('--fault-time must be before the end of --duration')
        build_swarm(cases[0], config, config['seed'])
    except (ShapeError, ScenarioError, RobotTypeError, PartitionError) as exc:
        print(f'fault_study.py: {exc}', file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [config['seed'] + k for k in range(config['seeds'])]
    jobs = [(case, seed) for case in cases for seed in seeds]
    rows: list[dict] = []
    from tqdm import tqdm

    if config['workers'] == 1:
        for case, seed in tqdm(jobs, unit='trial', desc='faults'):
            rows.append(run_case(case, config, seed))
    else:
        with futures.ProcessPoolExecutor(max_workers=config['workers']) as pool:
            pending = [pool.submit(run_case, case, config, seed) for case, seed in jobs]
            for job in tqdm(futures.as_completed(pending), total=len(pending), unit='trial',
                            desc='faults'):
                rows.append(job.result())
    order = {c['name']: k for k, c in enumerate(cases)}
    rows.sort(key=lambda r: (order[r['case']], r['seed']))
    summary = summarise(rows, cases)
    payload = {'config': config, 'command': ' '.join(['scripts/fault_study.py', *(
        argv if argv is not None else sys.argv[1:])]), 'cases': summary, 'trials': rows}
    (out / 'faults.json').write_text(json.dumps(_finite(payload), indent=2,
                                                default=_json_default), encoding='utf-8')
    (out / 'faults.md').write_text(markdown_table(summary), encoding='utf-8')
    plot(out / 'faults.png', summary)
    print(markdown_table(summary))
    print(f'fault study: {len(rows)} trials -> {out}')
    return 0


def _finite(value: Any) -> Any:
    """NaN and infinities as None, so that faults.json is strict JSON."""
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (float, np.floating)) and not math.isfinite(value):
        return None
    return value


def _json_default(value: Any) -> Any:
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


if __name__ == '__main__':
    sys.exit(main())
