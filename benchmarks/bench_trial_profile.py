#!/usr/bin/env python3
"""Where one evaluator trial's CPU time goes: frame deliveries by kind and brain steps.

Runs the 50-agent thesis scenario (``swarm_eval.scenario.run_trial(ScenarioSpec(),
seed)``) with the evaluator's hand-over of each transmission to its receivers
(``reception.receive``) and ``AgentBrain.step`` timed by ``time.process_time`` around
each call (the clock reads add to the run), transmissions sorted by kind: heartbeat,
route dump (full or incremental), flood (its deliveries counted as first copies and
duplicates), routed data. Prints per kind the transmissions, the deliveries, CPU seconds,
microseconds per delivery and share of the run, the brain steps taken and rested
(``brain_steps``) and why the active ones were active, with their CPU. docs/throughput.md shows its
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

    def timed_receive(t, packet, heard):     # heard: a reception.Receivers
        brains = heard.brains
        kind = KINDS.get(packet.kind, 'other kinds')
        if kind == 'flood':
            key = wire.routed_key(packet.payload)
            duplicates = sum(key in brain.router._seen for brain in brains)
            count['- of which duplicates'] += duplicates
        count[kind] += len(brains)
        sent[kind] += 1
        t0 = clock()
        receive(t, packet, heard)
        cost[kind] += clock() - t0

    reason: dict[int, str] = {}    # brain -> why its next step is active

    def timed_step(self, t):
        t0 = clock()
        out = step(self, t)
        spent = clock() - t0
        cost['brain step'] += spent
        count['brain step'] += 1
        sent['brain step'] += 1
        cost[f'step: {reason.pop(id(self), "not asked to rest")}'] += spent
        return out

    def counted_rest(self, t):
        if rest(self, t):
            return True
        moving = (self._parked_since is None or not self._parked or self._commanded
                  or self._yielding)
        if t >= self._next_outer:
            key = 'outer loop due'
        elif not self.config.is_beacon and t >= self._next_localization:
            key = 'localization due'
        elif not self.router.idle(t):
            key = 'router timer due'
        elif moving:
            key = 'moving (inner loop only)'
        elif self._avoid_due:
            key = 'proximity scan to act on'
        else:
            key = 'frames to send'
        why[key] += 1
        reason[id(self)] = key
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
    for kind in sorted((k for k in cost if not k.startswith('step: ')),
                       key=lambda k: -cost[k]):
        print(f'{kind:<22} {sent[kind]:>9,} {count[kind]:>10,} {cost[kind]:>8.2f} '
              f'{1e6 * cost[kind] / max(count[kind], 1):>8.1f} {cost[kind] / total:>6.1%}')
        if kind == 'flood':
            print(f'{"- of which duplicates":<22} {"":>9} '
                  f'{count["- of which duplicates"]:>10,}')
    rest = total - sum(v for k, v in cost.items() if not k.startswith('step: '))
    print(f'{"everything else":<20} {"":>10} {rest:>8.2f} {"":>8} {rest / total:>6.1%}')
    print('brain steps:', record.metrics['brain_steps'])
    print('active brain steps by what was due (the first of outer loop, localization,'
          ' router timer, moving, scan, frames), CPU s and us a step:')
    for key, n in sorted(why.items(), key=lambda kv: -kv[1]):
        spent = cost[f'step: {key}']
        print(f'  {key:<28} {n:>9,} {spent:>8.2f} {1e6 * spent / max(n, 1):>8.1f}')


if __name__ == '__main__':
    main()
