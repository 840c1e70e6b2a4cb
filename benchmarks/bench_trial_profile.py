#!/usr/bin/env python3
"""Where one evaluator trial's CPU time goes: frame deliveries by kind and brain steps.

Runs the 50-agent thesis scenario (``swarm_eval.scenario.run_trial(ScenarioSpec(),
seed)``) with the evaluator's hand-over of each transmission to its receivers
(``reception.receive``) and ``AgentBrain.step`` timed by ``time.process_time`` around
each call (the clock reads add to the run), transmissions sorted by kind: heartbeat,
route dump (full or incremental), flood (its deliveries counted as first copies and
duplicates), routed data. Prints per kind the transmissions, the deliveries, CPU seconds,
microseconds per delivery and share of the run, the brain steps taken and rested
(``brain_steps``) and why the active ones were active. docs/throughput.md shows its
figures.

  scripts/env.sh python benchmarks/bench_trial_profile.py --seed 0
"""

from __future__ import annotations

import argparse
from collections import defaultdict
import time

from swarm_agent import wire
from swarm_agent.brain import AgentBrain
from swarm_eval.scenario import run_trial, ScenarioSpec
from swarm_sim import headless

KINDS = {0: 'heartbeat', 1: 'route dump', 2: 'route dump', 3: 'routed data', 4: 'flood'}


def instrument(cost: dict, count: dict, sent: dict, why: dict) -> None:
    """Wrap the evaluator's frame hand-over and the brain's entry points with timers
    (for this process)."""
    clock = time.process_time
    receive, step, rest = headless.receive, AgentBrain.step, AgentBrain.rest

    def timed_receive(t, packet, brains):
        kind = KINDS.get(packet.kind, 'other kinds')
        if kind == 'flood':
            key = wire.routed_key(packet.payload)
            duplicates = sum(key in brain.router._seen for brain in brains)
            count['- of which duplicates'] += duplicates
        count[kind] += len(brains)
        sent[kind] += 1
        t0 = clock()
        receive(t, packet, brains)
        cost[kind] += clock() - t0

    def timed_step(self, t):
        t0 = clock()
        out = step(self, t)
        cost['brain step'] += clock() - t0
        count['brain step'] += 1
        sent['brain step'] += 1
        return out

    def counted_rest(self, t):
        if rest(self, t):
            return True
        if self._parked_since is None or not self._parked or self._commanded \
                or self._yielding:
            why['moving'] += 1
        elif t >= self._next_outer:
            why['outer loop due'] += 1
        elif not self.config.is_beacon and t >= self._next_localization:
            why['localization due'] += 1
        elif self._avoid_due:
            why['proximity scan to act on'] += 1
        elif self._outbox:
            why['frames to send'] += 1
        else:
            why['router timer due'] += 1
        return False

    headless.receive = timed_receive
    AgentBrain.step, AgentBrain.rest = timed_step, counted_rest


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seed', type=int, default=0, help='trial seed (default 0)')
    args = parser.parse_args()
    cost, count, sent, why = (defaultdict(float), defaultdict(int), defaultdict(int),
                              defaultdict(int))
    instrument(cost, count, sent, why)
    t0, w0 = time.process_time(), time.perf_counter()
    record = run_trial(ScenarioSpec(), args.seed)
    total, wall = time.process_time() - t0, time.perf_counter() - w0
    print(f'seed {args.seed}: {record.times[-1]:.1f} sim-s, {total:.1f} CPU-s, '
          f'{wall:.1f} wall-s, settling time {record.metrics["settling_time"]}')
    print(f'{"work":<22} {"calls":>9} {"deliveries":>10} {"CPU s":>8} {"us each":>8} '
          f'{"share":>6}')
    for kind in sorted(cost, key=lambda k: -cost[k]):
        print(f'{kind:<22} {sent[kind]:>9,} {count[kind]:>10,} {cost[kind]:>8.2f} '
              f'{1e6 * cost[kind] / max(count[kind], 1):>8.1f} {cost[kind] / total:>6.1%}')
        if kind == 'flood':
            print(f'{"- of which duplicates":<22} {"":>9} '
                  f'{count["- of which duplicates"]:>10,}')
    rest = total - sum(cost.values())
    print(f'{"everything else":<20} {"":>10} {rest:>8.2f} {"":>8} {rest / total:>6.1%}')
    print('brain steps:', record.metrics['brain_steps'])
    print('active because:', dict(sorted(why.items(), key=lambda kv: -kv[1])))


if __name__ == '__main__':
    main()
