"""A deterministic network of DSDV routers for tests and benchmarks (thesis 3.1.2).

Routers are joined by an adjacency set instead of a radio: at each time ``t`` every
living router ticks, then its frames are handed to the routers adjacent to the sender
(every neighbour for a broadcast, the addressee for a unicast), each receiver losing a
frame with probability ``loss`` (seeded), and whatever a receiver sends in reply is
delivered the same way within the same instant. With heartbeats and full dumps every
``dt``, information travels exactly one hop per instant (an *iteration* of the thesis,
Figs. 3.5-3.9). ``swarm_sim.medium.RadioMedium`` is the radio with geometry, latency
and airtime; this loop isolates the routing protocol.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from swarm_agent.dsdv import Delivered, DsdvConfig, DsdvRouter
from swarm_agent.packet import BROADCAST, MAX_PAYLOAD, Packet
from swarm_agent.wire import INFINITE_HOPS


class SimulatedNet:
    """Routers on an adjacency set; synchronous instants, optional seeded loss."""

    def __init__(self, ids: Iterable[int], edges: Iterable[tuple[int, int]],
                 config: DsdvConfig | None = None, loss: float = 0.0,
                 rng: np.random.Generator | None = None) -> None:
        if not 0.0 <= loss < 1.0:
            raise ValueError(f'loss must be in [0, 1), got {loss}')
        self.routers = {i: DsdvRouter(i, config or DsdvConfig()) for i in ids}
        self.adj: dict[int, set[int]] = {i: set() for i in self.routers}
        for a, b in edges:
            self.link(a, b)
        self.alive = set(self.routers)
        self.loss = loss
        self.rng = rng or np.random.default_rng(0)
        self.delivered: dict[int, list[Delivered]] = {i: [] for i in self.routers}
        self.frames = 0
        self.bytes = 0

    def link(self, a: int, b: int) -> None:
        self.adj[a].add(b)
        self.adj[b].add(a)

    def unlink(self, a: int, b: int) -> None:
        self.adj[a].discard(b)
        self.adj[b].discard(a)

    def kill(self, a: int) -> None:
        """The agent vanishes (Fig. 3.6): it neither sends nor hears anything."""
        self.alive.discard(a)

    def transmit(self, t: float, sender: int, packets: list[Packet]) -> None:
        """Deliver frames (and everything they cause) within the instant ``t``.

        Raises ValueError on a frame the radio could not carry (longer than
        ``MAX_PAYLOAD``) or sent under another router's address: router bugs.
        """
        queue = deque((sender, p) for p in packets)
        while queue:
            src, packet = queue.popleft()
            if len(packet.payload) > MAX_PAYLOAD or packet.source != src:
                raise ValueError(f'router {src} sent a bad frame: source {packet.source}, '
                                 f'{len(packet.payload)} bytes (at most {MAX_PAYLOAD})')
            self.frames += 1
            self.bytes += len(packet.payload)
            if packet.destination == BROADCAST:
                receivers = sorted(self.adj[src])
            else:
                receivers = [packet.destination] if packet.destination in self.adj[src] else []
            for r in receivers:
                if r not in self.alive or (self.loss and self.rng.random() < self.loss):
                    continue
                out = self.routers[r].on_packet(t, packet)
                self.delivered[r].extend(out.delivered)
                queue.extend((r, p) for p in out.packets)

    def step(self, t: float) -> None:
        """Every living router ticks at ``t``, then all its frames go out."""
        outs = {i: self.routers[i].tick(t) for i in sorted(self.alive)}
        for i, packets in outs.items():
            self.transmit(t, i, packets)

    def table(self, node: int) -> dict[int, tuple[int, int, int]]:
        """destination -> (next hop, hops, sequence number)."""
        return {r.destination: (r.next_hop, r.hop_count, r.sequence_number)
                for r in self.routers[node].routes()}

    def hop_distances(self) -> np.ndarray:
        """Shortest path lengths in hops between the routers in sorted id order (inf when
        disconnected), over the living routers' links."""
        ids = sorted(self.routers)
        pos = {a: k for k, a in enumerate(ids)}
        rows = [pos[a] for a in ids if a in self.alive for b in self.adj[a] if b in self.alive]
        cols = [pos[b] for a in ids if a in self.alive for b in self.adj[a] if b in self.alive]
        m = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(ids), len(ids))).tocsr()
        return shortest_path(m, directed=False, unweighted=True)

    def converged(self, dist: np.ndarray) -> bool:
        """Every living router's route hop counts equal ``dist`` (from
        ``hop_distances``), unreachable destinations have none, and every next hop is
        one hop closer."""
        ids = sorted(self.routers)
        pos = {a: k for k, a in enumerate(ids)}
        n = len(ids)
        hops = np.full((n, n), np.inf)
        nxt = np.zeros((n, n), dtype=int)
        for i, a in enumerate(ids):
            if a not in self.alive:
                continue            # a dead router's row: nothing (dist is inf there too)
            for d, e in self.routers[a].table.items():
                if e.hop_count < INFINITE_HOPS and d in pos:
                    hops[i, pos[d]] = e.hop_count
                    nxt[i, pos[d]] = pos.get(e.next_hop, i)
        np.fill_diagonal(hops, 0.0)
        if not np.array_equal(hops, dist):
            return False
        i, d = np.nonzero(np.isfinite(dist) & (dist > 0))
        return bool(np.all(dist[nxt[i, d], d] == dist[i, d] - 1))

    def run_until_converged(self, t0: float, dt: float, t_max: float) -> float | None:
        """Step at t0, t0 + dt, ... until ``converged`` (checked after each step) for the
        current links; the time it first held, or None when not by ``t_max``."""
        dist = self.hop_distances()
        t = t0
        while t <= t_max + 1e-9:
            self.step(t)
            if self.converged(dist):
                return t
            t += dt
        return None
