"""DSDV convergence after link changes versus network size and packet loss, and routing traffic.

For each agent count (random geometric graphs at the density of thesis chapter 4: 50
agents in 100 m x 100 m, 25 m radio range), each per-receiver loss probability and
each seed, the real ``DsdvRouter``s (default timers: heartbeat 0.5 s, full dump 2 s,
triggered updates every 0.25 s) run in the network loop of ``swarm_agent.sim_net``
(the one the DSDV unit tests use) in synchronous 0.25 s ticks. Measured, in simulated
time until every route equals the BFS shortest path with a next hop one hop closer:

- cold start: from empty tables;
- link break: of 10 random links, the one carrying the most shortest paths goes
  down (includes the 2 s neighbour timeout);
- link addition: the two closest agents not yet linked come within range;
- routing traffic: payload bytes per second per agent (heartbeats, full dumps,
  incremental updates) over 10 s after the cold start, with and without the 18-byte
  XBee frame overhead.

Times are in full-dump periods (2 s). Per (agents, loss) the table gives the mean and
the worst over the seeds; a change that did not converge within --limit counts as
such. Writes bench_dsdv.json (every trial and the table rows) into --out when given.

  scripts/env.sh python benchmarks/bench_dsdv.py --agents 50,200 --loss 0,0.1,0.3 \\
      --seeds 5 --out results/bench_dsdv
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

from swarm_agent.dsdv import DsdvConfig
from swarm_agent.sim_net import SimulatedNet
from swarm_eval.paths import write_json
from swarm_sim.medium import FRAME_OVERHEAD_BYTES

TICK = 0.25
EVENTS = ('cold_start', 'link_break', 'link_addition')


def geometric_graph(n: int, seed: int, radius: float = 25.0
                    ) -> tuple[np.ndarray, set[tuple[int, int]]]:
    """n agents at the thesis density (50 per 100 m x 100 m)."""
    rng = np.random.default_rng(seed)
    side = 100.0 * np.sqrt(n / 50.0)
    pts = rng.uniform(-side / 2, side / 2, (n, 2))
    pairs = cKDTree(pts).query_pairs(radius)
    return pts, {(int(a), int(b)) for a, b in pairs}


def _converge(net: SimulatedNet, t: float, limit_s: float) -> tuple[float | None, float]:
    """(seconds until converged or None, the time after the last step)."""
    done = net.run_until_converged(t, TICK, t + limit_s)
    if done is None:
        return None, t + limit_s + TICK
    return done + TICK - t, done + TICK


def bench(n: int, seed: int, limit_s: float, loss: float = 0.0) -> dict:
    """One trial: convergence times (s, None when not within ``limit_s``) and routing
    traffic (benchmarks/run_all.py uses it too)."""
    pts, edges = geometric_graph(n, seed)
    config = DsdvConfig()
    net = SimulatedNet(range(n), edges, config, loss=loss,
                       rng=np.random.default_rng([seed, int(round(loss * 1000))]))
    wall = time.perf_counter()
    dist = net.hop_distances()
    finite = dist[np.isfinite(dist)]
    row: dict = {'agents': n, 'loss': loss, 'seed': seed, 'links': len(edges),
                 'diameter': int(finite.max()), 'mean_degree': 2 * len(edges) / n}
    row['cold_start_s'], t = _converge(net, 0.0, limit_s)
    # steady-state routing traffic
    net.frames = net.bytes = 0
    t0 = t
    while t < t0 + 10.0 - 1e-9:
        net.step(t)
        t += TICK
    secs = t - t0
    row['routing_bytes_per_s_per_agent'] = net.bytes / secs / n
    row['routing_bytes_per_s_per_agent_with_overhead'] = (
        (net.bytes + FRAME_OVERHEAD_BYTES * net.frames) / secs / n)
    row['frames_per_s_per_agent'] = net.frames / secs / n
    rng = np.random.default_rng(seed + 1)
    # link break: of 10 random links, the one whose loss changes the most shortest paths
    edge_list = sorted(edges)
    best = (-1, edge_list[0])
    for k in rng.choice(len(edge_list), min(10, len(edge_list)), replace=False):
        a, b = edge_list[int(k)]
        net.unlink(a, b)
        best = max(best, (int(np.sum(net.hop_distances() != dist) // 2), (a, b)))
        net.link(a, b)
    row['break_changed_pairs'], (a, b) = best
    net.unlink(a, b)
    row['link_break_s'], t = _converge(net, t, limit_s)
    net.link(a, b)
    _, t = _converge(net, t, limit_s)
    # link addition: the closest pair not yet linked comes within range
    before = net.hop_distances()
    pairs = cKDTree(pts).query_pairs(60.0, output_type='ndarray')
    gaps = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
    for k in np.argsort(gaps):
        i, j = (int(v) for v in pairs[k])
        if j not in net.adj[i] and np.isfinite(before[i, j]):
            net.link(i, j)
            row['addition_changed_pairs'] = int(np.sum(net.hop_distances() != before) // 2)
            row['link_addition_s'], t = _converge(net, t, limit_s)
            break
    row['wall_s'] = time.perf_counter() - wall
    return row


def aggregate(rows: list[dict], period: float) -> dict:
    """Mean and worst over seeds, in full-dump periods; None entries did not converge."""
    out: dict = {'agents': rows[0]['agents'], 'loss': rows[0]['loss'], 'seeds': len(rows),
                 'mean_diameter': float(np.mean([r['diameter'] for r in rows]))}
    for event in EVENTS:
        values = [r.get(event + '_s') for r in rows if event + '_s' in r]
        done = [v / period for v in values if v is not None]
        out[event + '_not_converged'] = sum(v is None for v in values)
        out[event + '_mean_periods'] = float(np.mean(done)) if done else None
        out[event + '_worst_periods'] = (None if len(done) < len(values) or not done
                                         else float(max(done)))
    for key in ('routing_bytes_per_s_per_agent', 'routing_bytes_per_s_per_agent_with_overhead',
                'frames_per_s_per_agent'):
        out[key] = float(np.mean([r[key] for r in rows]))
    return out


def _fmt(agg: dict, event: str) -> str:
    mean, worst = agg[event + '_mean_periods'], agg[event + '_worst_periods']
    missed = agg[event + '_not_converged']
    text = '-' if mean is None else f'{mean:.2f}'
    text += ' / ' + ('-' if worst is None else f'{worst:.2f}')
    return text + (f' ({missed} not converged)' if missed else '')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--agents', default='50,200,1000')
    parser.add_argument('--loss', default='0,0.1,0.3',
                        help='per-receiver frame loss probabilities, comma separated')
    parser.add_argument('--seeds', type=int, default=5)
    parser.add_argument('--seed', type=int, default=0, help='first seed')
    parser.add_argument('--limit', type=float, default=120.0,
                        help='give up on convergence after this many simulated seconds')
    parser.add_argument('--out', default='')
    args = parser.parse_args(argv)
    try:
        sizes = [int(v) for v in args.agents.split(',')]
        if min(sizes) < 2:
            raise ValueError
    except ValueError:
        print('bench_dsdv: error: --agents must be integers >= 2 like 50,200,1000',
              file=sys.stderr)
        return 2
    try:
        losses = [float(v) for v in args.loss.split(',')]
        if not all(0.0 <= v < 1.0 for v in losses):
            raise ValueError
    except ValueError:
        print('bench_dsdv: error: --loss must be probabilities in [0, 1) like 0,0.1,0.3',
              file=sys.stderr)
        return 2
    if args.seeds < 1 or not (math.isfinite(args.limit) and args.limit > 0):
        print('bench_dsdv: error: --seeds must be >= 1 and --limit positive', file=sys.stderr)
        return 2
    period = DsdvConfig().full_dump_period_s
    rows, table = [], []
    print('| agents | loss | mean diameter | cold start (periods, mean / worst) | link break '
          '| link addition | routing B/s per agent (payload / on air) |')
    print('|---|---|---|---|---|---|---|')
    for n in sizes:
        for loss in losses:
            trials = []
            for seed in range(args.seed, args.seed + args.seeds):
                trials.append(bench(n, seed, args.limit, loss))
                r = trials[-1]
                print(f'bench_dsdv: {n} agents, loss {loss:g}, seed {seed}: cold start '
                      f'{r["cold_start_s"]} s, link break {r["link_break_s"]} s, link addition '
                      f'{r.get("link_addition_s")} s; wall {r["wall_s"]:.0f} s',
                      file=sys.stderr, flush=True)
            rows.extend(trials)
            agg = aggregate(trials, period)
            agg['wall_s'] = float(sum(r['wall_s'] for r in trials))
            table.append(agg)
            print(f'| {n} | {100 * loss:.0f} % | {agg["mean_diameter"]:.1f} | '
                  f'{_fmt(agg, "cold_start")} | {_fmt(agg, "link_break")} | '
                  f'{_fmt(agg, "link_addition")} | {agg["routing_bytes_per_s_per_agent"]:.0f} / '
                  f'{agg["routing_bytes_per_s_per_agent_with_overhead"]:.0f} |', flush=True)
    if args.out:
        write_json(args.out, 'bench_dsdv.json', {'period_s': period, 'table': table,
                                                 'trials': rows})
    return 0



if __name__ == '__main__':
    sys.exit(main())
