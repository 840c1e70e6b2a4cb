#!/usr/bin/env python3
"""DSDV convergence after a link change versus network diameter, and routing traffic.

For 50, 200 and 1000 agents on random geometric graphs at the density of thesis
chapter 4 (50 agents in 100 m x 100 m, 25 m radio range), the real ``DsdvRouter``s
(default timers: heartbeat 0.5 s, full dump 2 s, triggered updates every 0.25 s)
run in synchronous 0.25 s ticks without loss. Measured, in simulated time:

- cold start: time until every route equals the BFS shortest path;
- link break: of 10 random links, the one carrying the most shortest paths goes
  down; time until the tables match the new graph (includes the 2 s neighbour
  timeout);
- link addition: two agents just out of range come within range;
- routing traffic: payload bytes per second per agent (heartbeats, full dumps,
  incremental updates) over 10 s of steady state, with and without the 18-byte
  XBee frame overhead.

Times are printed in seconds and in full-dump periods (2 s). Writes bench_dsdv.json
into --out when given.

  scripts/env.sh python benchmarks/bench_dsdv.py --agents 50,200,1000
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path
from scipy.spatial import cKDTree

from swarm_agent.dsdv import DsdvConfig, DsdvRouter
from swarm_agent.packet import BROADCAST
from swarm_agent.wire import INFINITE_HOPS
from swarm_sim.medium import FRAME_OVERHEAD_BYTES

TICK = 0.25


class Network:
    """Routers on an adjacency set, synchronous ticks, no loss."""

    def __init__(self, n: int, edges: set[tuple[int, int]]) -> None:
        self.n = n
        self.config = DsdvConfig()
        self.routers = [DsdvRouter(i, self.config) for i in range(n)]
        self.adj: list[set[int]] = [set() for _ in range(n)]
        for a, b in edges:
            self.link(a, b)
        self.t = 0.0
        self.frames = 0
        self.bytes = 0

    def link(self, a: int, b: int) -> None:
        self.adj[a].add(b)
        self.adj[b].add(a)

    def unlink(self, a: int, b: int) -> None:
        self.adj[a].discard(b)
        self.adj[b].discard(a)

    def step(self) -> None:
        outs = [r.tick(self.t) for r in self.routers]
        for packets in outs:
            queue = list(packets)
            while queue:
                packet = queue.pop()
                self.frames += 1
                self.bytes += len(packet.payload)
                src = packet.source
                receivers = (self.adj[src] if packet.destination == BROADCAST
                             else {packet.destination} & self.adj[src])
                for r in receivers:
                    queue.extend(self.routers[r].on_packet(self.t, packet).packets)
        self.t += TICK

    def distances(self) -> np.ndarray:
        rows = [a for a in range(self.n) for _ in self.adj[a]]
        cols = [b for a in range(self.n) for b in self.adj[a]]
        m = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(self.n, self.n)).tocsr()
        return shortest_path(m, directed=False, unweighted=True)

    def converged(self, dist: np.ndarray) -> bool:
        """Every route's hops equal BFS and its next hop is one hop closer."""
        hops = np.full((self.n, self.n), np.inf)
        nxt = np.zeros((self.n, self.n), dtype=int)
        for i, r in enumerate(self.routers):
            for d, e in r.table.items():
                if e.hop_count < INFINITE_HOPS:
                    hops[i, d] = e.hop_count
                    nxt[i, d] = e.next_hop
        np.fill_diagonal(hops, 0.0)
        if not np.array_equal(hops, dist):
            return False
        i, d = np.nonzero(np.isfinite(dist) & (dist > 0))
        return bool(np.all(dist[nxt[i, d], d] == dist[i, d] - 1))

    def run_until_converged(self, limit_s: float) -> float | None:
        """Seconds from now until converged (checked after each tick), or None."""
        dist = self.distances()
        start = self.t
        while self.t - start <= limit_s:
            self.step()
            if self.converged(dist):
                return self.t - start
        return None


def geometric_graph(n: int, seed: int, radius: float = 25.0
                    ) -> tuple[np.ndarray, set[tuple[int, int]]]:
    """n agents at the thesis density (50 per 100 m x 100 m)."""
    rng = np.random.default_rng(seed)
    side = 100.0 * np.sqrt(n / 50.0)
    pts = rng.uniform(-side / 2, side / 2, (n, 2))
    pairs = cKDTree(pts).query_pairs(radius)
    return pts, {(int(a), int(b)) for a, b in pairs}


def bench(n: int, seed: int, limit_s: float) -> dict:
    pts, edges = geometric_graph(n, seed)
    net = Network(n, edges)
    wall = time.perf_counter()
    dist = net.distances()
    finite = dist[np.isfinite(dist)]
    row: dict = {'agents': n, 'links': len(edges), 'diameter': int(finite.max()),
                 'mean_degree': 2 * len(edges) / n,
                 'connected_pairs_share': float(np.isfinite(dist).mean())}
    row['cold_start_s'] = net.run_until_converged(limit_s)
    # steady-state routing traffic
    net.frames = net.bytes = 0
    t0 = net.t
    for _ in range(int(10.0 / TICK)):
        net.step()
    secs = net.t - t0
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
        best = max(best, (int(np.sum(net.distances() != dist) // 2), (a, b)))
        net.link(a, b)
    row['break_changed_pairs'], (a, b) = best
    net.unlink(a, b)
    row['link_break_s'] = net.run_until_converged(limit_s)
    net.link(a, b)
    assert net.run_until_converged(limit_s) is not None
    # link addition: the closest pair not yet linked comes within range
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2) if n <= 1500 else None
    best, pair = np.inf, None
    for i in range(n):
        for j in np.argsort(d[i])[1:40]:
            j = int(j)
            if j not in net.adj[i] and d[i, j] < best and np.isfinite(dist[i, j]):
                best, pair = d[i, j], (i, j)
    if pair is not None:
        before = net.distances()
        net.link(*pair)
        row['addition_changed_pairs'] = int(np.sum(net.distances() != before) // 2)
        row['link_addition_s'] = net.run_until_converged(limit_s)
    row['wall_s'] = time.perf_counter() - wall
    period = net.config.full_dump_period_s
    for key in ('cold_start_s', 'link_break_s', 'link_addition_s'):
        value = row.get(key)
        row[key[:-2] + '_periods'] = None if value is None else value / period
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--agents', default='50,200,1000')
    parser.add_argument('--seed', type=int, default=0)
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
    rows = []
    for n in sizes:
        row = bench(n, args.seed, args.limit)
        rows.append(row)

        def fmt(key: str, row: dict = row) -> str:
            v = row.get(key)
            return 'not converged' if v is None else f'{v:.2f} s = {v / 2.0:.2f} periods'

        print(f'{n:5d} agents, diameter {row["diameter"]:2d}, degree {row["mean_degree"]:.1f}: '
              f'cold start {fmt("cold_start_s")}; link break {fmt("link_break_s")} '
              f'({row["break_changed_pairs"]} pairs changed); link addition '
              f'{fmt("link_addition_s")}; routing {row["routing_bytes_per_s_per_agent"]:.0f}'
              f' B/s/agent payload, '
              f'{row["routing_bytes_per_s_per_agent_with_overhead"]:.0f} B/s/agent on air '
              f'({row["frames_per_s_per_agent"]:.1f} frames/s); wall {row["wall_s"]:.1f} s',
              flush=True)
    if args.out:
        out = pathlib.Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / 'bench_dsdv.json').write_text(json.dumps(rows, indent=2) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
