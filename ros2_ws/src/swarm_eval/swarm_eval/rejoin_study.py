"""How fast a restarted agent rejoins the mesh (DSDV, thesis 3.1.2; docs/restarts.md).

One trial: the evaluator's swarm (``swarm_eval.scenario``) runs to ``restart_s``; then
one agent's brain is dropped and a fresh one booted (``HeadlessSwarm.restart``, the body
stays). Every ``PROBE_S`` after that the study checks the agents that were the agent's
neighbours at the crash (its old router's ``heard`` set): the agent is *back* in a
neighbour's route table when that neighbour holds a finite route to it whose sequence
number is newer (RFC 1982 order, ``dsdv.seq_newer``) than every number the previous run
sent. Before that, the neighbour's route to it is the old run's, which DSDV can
neither refresh nor tell from a stale one. The rejoin time is the first probe at which
every such neighbour that is still alive has it back; the target is 3 DSDV periods
(``full_dump_period_s``, 2 s).

``from_zero`` restarts the router from sequence 0 (what every boot did before
``dsdv.boot_sequence``): the measure of the problem of issue 24.

  scripts/env.sh python scripts/rejoin_study.py --restarts 10
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import math
import sys

import numpy as np

from swarm_agent.dsdv import seq_newer
from swarm_agent.wire import INFINITE_HOPS
from swarm_eval.scenario import build_scenario, ScenarioSpec
from swarm_sim.headless import HeadlessSwarm

PROBE_S = 0.1   # probe period (s): the medium's link update period
REJOIN_STREAM = 0x524A   # seeds the restart offsets apart from the trials


@dataclass
class Rejoin:
    """One restart: who, when, and how long until every neighbour had it back."""

    seed: int
    agent: int
    restart_s: float
    neighbours: int
    old_sequence: int            # the last own number of the previous run
    new_sequence: int            # the first own number of the new run
    rejoin_s: float              # math.inf: not within the horizon
    dsdv_period_s: float

    @property
    def periods(self) -> float:
        """The rejoin time in DSDV full-dump periods."""
        return self.rejoin_s / self.dsdv_period_s


def measure_rejoin(spec: ScenarioSpec, seed: int, agent_index: int, restart_s: float,
                   horizon_s: float = 20.0, from_zero: bool = False,
                   half_size: float | None = None) -> Rejoin:
    """Run one trial with one restart and measure the rejoin (module docstring).

    ``agent_index`` picks the agent among the non-beacons (all agents when every one is
    a beacon), modulo their count;
    ``half_size`` (m) overrides the deployment area's half width (default 50).
    """
    scenario = build_scenario(spec, seed)
    if half_size is not None:
        scenario.half_size = half_size
    scenario.duration_s = restart_s + horizon_s
    scenario.min_duration_s = scenario.duration_s   # never stop settled before the end
    swarm = HeadlessSwarm(scenario)
    movers = [a for a, b in zip(swarm.ids, swarm.is_beacon) if not b] or list(swarm.ids)
    agent = movers[agent_index % len(movers)]
    i = swarm.index[agent]
    state: dict = {}

    def crash(sw: HeadlessSwarm, t: float) -> None:
        old = sw.brains[i].router
        state['old'] = old.sequence
        state['neighbours'] = sorted(old.heard)
        sw.restart(t, [agent], boot_time_s=0.0 if from_zero else None)
        state['new'] = sw.brains[i].router.sequence

    def probe(sw: HeadlessSwarm, t: float) -> None:
        if 'rejoin' in state:
            return
        for j in state['neighbours']:
            brain = sw.brains[sw.index[j]]
            if brain is None:
                continue
            route = brain.router.table.get(agent)
            if (route is None or route.hop_count >= INFINITE_HOPS
                    or not seq_newer(route.sequence_number, state['old'])):
                return
        state['rejoin'] = t - restart_s

    probes = [(restart_s + k * PROBE_S, probe)
              for k in range(1, int(round(horizon_s / PROBE_S)) + 1)]
    scenario.events = [(restart_s, crash), *probes]
    swarm.run()
    period = swarm.brains[i].router.config.full_dump_period_s
    return Rejoin(seed, agent, restart_s, len(state['neighbours']), state['old'],
                  state['new'], state.get('rejoin', math.inf), period)


def study(spec: ScenarioSpec, restarts: int, restart_s: float, horizon_s: float,
          from_zero: bool) -> list[Rejoin]:
    """``restarts`` trials, seed k restarting non-beacon k * 7 at ``restart_s`` plus a
    seeded offset within one DSDV period (the crash falls anywhere in the dump cycle)."""
    rows = []
    for seed in range(restarts):
        offset = float(np.random.default_rng([REJOIN_STREAM, seed]).uniform(0.0, 2.0))
        rows.append(measure_rejoin(spec, seed, 7 * seed, restart_s + offset, horizon_s,
                                   from_zero))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--agents', type=int, default=50)
    parser.add_argument('--shape', default='circle_314')
    parser.add_argument('--restarts', type=int, default=10, help='trials (one restart each)')
    parser.add_argument('--at', type=float, default=30.0, help='restart time, s (plus an '
                        'offset within one DSDV period)')
    parser.add_argument('--horizon', type=float, default=20.0, help='observed after, s')
    parser.add_argument('--loss', type=float, default=0.0, help='frame loss, 0..1')
    args = parser.parse_args(argv)
    if args.restarts <= 0 or args.at <= 0.0 or args.horizon <= 0.0:
        print('rejoin_study: error: --restarts, --at and --horizon must be positive',
              file=sys.stderr)
        return 2
    spec = ScenarioSpec(agents=args.agents, shape=args.shape, loss=args.loss,
                        duration=args.at + 2.0 + args.horizon)
    try:
        results = {mode: study(spec, args.restarts, args.at, args.horizon, mode == 'zero')
                   for mode in ('zero', 'boot')}
    except (ValueError, KeyError) as exc:
        print(f'rejoin_study: error: {exc}', file=sys.stderr)
        return 2
    print('seed agent restart_s neighbours old_seq | from 0: new_seq rejoin_s | boot time: '
          'new_seq rejoin_s')
    for z, b in zip(results['zero'], results['boot']):
        print(f'{z.seed:4d} {z.agent:5d} {z.restart_s:9.2f} {z.neighbours:10d} '
              f'{z.old_sequence:7d} | {z.new_sequence:7d} {z.rejoin_s:8.1f} | '
              f'{b.new_sequence:9d} {b.rejoin_s:8.1f}')
    for mode, rows in results.items():
        times = np.array([r.rejoin_s for r in rows])
        periods = times / rows[0].dsdv_period_s
        print(f'{mode:>4}: rejoin mean {times.mean():.2f} s, max {times.max():.2f} s = '
              f'{periods.max():.2f} DSDV periods; within 3 periods: '
              f'{int((periods <= 3.0).sum())}/{len(rows)}')
    worst = max(r.periods for r in results['boot'])
    return 0 if worst <= 3.0 else 1
