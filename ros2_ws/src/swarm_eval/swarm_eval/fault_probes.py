"""Probes of a fault-study trial: DSDV health, link-graph components, beacons heard,
goals claimed and reached, agreement after the fault, and the pass verdict (issue 10).
Each reads a headless swarm or a record of truth and belief (headless or ROS alike)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree

from swarm_agent.wire import INFINITE_HOPS
from swarm_sim.headless import HeadlessSwarm, TrialRecord
from swarm_sim.medium import RadioMedium
from swarm_sim.metrics import agreement_by_sample

GOAL_TOLERANCE_M = 1.5      # a goal counts as covered by an agent of its type this close
SAMPLE_EVERY = 4            # route tables sampled every 4th record frame (2 s)


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

