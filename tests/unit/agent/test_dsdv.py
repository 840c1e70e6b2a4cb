"""DSDV routing (thesis 3.1.2): the thesis's own examples, properties and the data plane.

The routers run in the deterministic network loop of ``swarm_agent.sim_net`` (shared
with benchmarks/bench_dsdv.py): at each time ``t`` every living router ticks, then its
frames are handed to the routers on the adjacency set (every neighbour for a
broadcast, the addressee for a unicast), and whatever a receiver sends in reply is
delivered the same way within the same instant. An *iteration* of the thesis (Figs.
3.5-3.9) is one such instant with ``ITERATION``: heartbeat and full dump every second,
so information travels exactly one hop per iteration.

The figure images are not in the thesis text; the graphs below follow their
descriptions (names A, B, ... mapped to ids 1, 2, ...).
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from scipy.sparse.csgraph import shortest_path

from swarm_agent import wire
from swarm_agent.dsdv import Delivered, DsdvConfig
from swarm_agent.packet import Kind, MAX_BODY
from swarm_agent.sim_net import SimulatedNet as Net
from swarm_agent.wire import INFINITE_HOPS

A, B, C, D, E, F, G = range(1, 8)
ITERATION = DsdvConfig(heartbeat_period_s=1.0, full_dump_period_s=1.0,
                       neighbour_timeout_s=2.0, incremental_min_interval_s=1.0)
PROPERTY = settings(max_examples=25, deadline=None)
# The route table's rules run as kernels (swarm_agent.route_table): compiled and as source.
pytestmark = pytest.mark.usefixtures('kernels')


def _bfs(ids: list[int], adj: dict[int, set[int]]) -> np.ndarray:
    """Unweighted shortest path lengths (hops) between all pairs; inf when disconnected."""
    pos = {a: k for k, a in enumerate(ids)}
    m = np.zeros((len(ids), len(ids)))
    for a in ids:
        for b in adj[a]:
            m[pos[a], pos[b]] = 1.0
    return shortest_path(m, directed=False, unweighted=True)


def _walk(net: Net, src: int, dst: int) -> list[int] | None:
    """The path the next hops give from src to dst; None on a dead end; raises on a loop."""
    path = [src]
    while path[-1] != dst:
        hop = net.routers[path[-1]].next_hop(dst)
        if hop is None:
            return None
        if hop in path:
            raise AssertionError(f'routing loop towards {dst}: {path + [hop]}')
        path.append(hop)
    return path


def _wrong_routes(net: Net, dist: np.ndarray) -> list[str]:
    """Every route that disagrees with the BFS distances (empty when converged)."""
    ids = sorted(net.routers)
    pos = {a: k for k, a in enumerate(ids)}
    wrong = []
    for i in ids:
        for j in ids:
            if i == j:
                continue
            d = dist[pos[i], pos[j]]
            route = net.routers[i].table.get(j)
            hops = route.hop_count if route else INFINITE_HOPS
            if np.isinf(d):
                if hops < INFINITE_HOPS:
                    wrong.append(f'{i}->{j}: route of {hops} hops to an unreachable node')
                continue
            if hops != d:
                wrong.append(f'{i}->{j}: {hops} hops, shortest is {int(d)}')
                continue
            path = _walk(net, i, j)
            if path is None or len(path) - 1 != d:
                wrong.append(f'{i}->{j}: next hops give {path}')
    return wrong


def _run_until_converged(net: Net, t0: float, dt: float, t_max: float) -> float | None:
    """Step until every route matches BFS; the time it did, or None."""
    dist = _bfs(sorted(net.routers), net.adj)
    t = t0
    while t <= t_max:
        net.step(t)
        if not _wrong_routes(net, dist):
            return t
        t += dt
    return None


# --------------------------------------------------------------------- thesis figures
FIG35_EDGES = [(A, B), (A, C), (B, C), (B, D), (C, E), (D, E), (D, F), (E, F), (F, G)]
FIG35_FROM_B = {A: 1, C: 1, D: 1, E: 2, F: 2, G: 3}


def test_fig35_costs_from_b_correct_after_three_iterations():
    """Fig. 3.5: from 'all costs infinite' to B's shortest hop counts in 3 iterations."""
    net = Net(range(A, G + 1), FIG35_EDGES, ITERATION)
    for it in range(2):
        net.step(float(it))
    # after two iterations the node three hops away is still unknown
    assert G not in net.routers[B].reachable()
    net.step(2.0)
    table = net.table(B)
    assert {d: table[d][1] for d in table} == FIG35_FROM_B
    dist = _bfs(sorted(net.routers), net.adj)
    assert not [w for w in _wrong_routes(net, dist) if w.startswith(f'{B}->')]
    # the whole network needs its diameter (4 hops, A to G) in iterations
    assert _wrong_routes(net, dist)
    net.step(3.0)
    assert not _wrong_routes(net, dist)


def test_fig36_lost_node_no_count_to_infinity():
    """Fig. 3.6: D vanishes from the chain A-B-C-D; no hop count climbs, D's routes die."""
    net = Net([A, B, C, D], [(A, B), (B, C), (C, D)], ITERATION)
    for it in range(4):
        net.step(float(it))
    before = {n: net.table(n)[D] for n in (A, B, C)}
    assert {n: before[n][1] for n in before} == {A: 3, B: 2, C: 1}
    net.kill(D)
    for it in range(4, 30):
        net.step(float(it))
        for n in (A, B, C):
            hops = net.table(n)[D][1]
            # Bellman-Ford would give C 3 hops via B, then B 4 via C, ... (Fig. 3.6)
            assert hops in (before[n][1], INFINITE_HOPS), (it, n, hops)
    for n in (A, B, C):
        _, hops, seq = net.table(n)[D]
        assert hops == INFINITE_HOPS
        assert seq % 2 == 1 and seq == before[C][2] + 1  # C's break number everywhere
        assert D not in net.routers[n].reachable()
        assert net.routers[n].reachable() == {A, B, C} - {n}


def test_fig38_link_addition():
    """Fig. 3.8: A links to B; B inserts <A, A, 1, s>, then C and D insert <A, B, 2, s>."""
    net = Net([A, B, C, D], [(B, C), (B, D), (C, D)], ITERATION)
    for it in range(3):
        net.step(float(it))
    assert all(A not in net.routers[n].table for n in (B, C, D))
    net.link(A, B)
    net.step(3.0)
    next_hop, hops, seq_a = net.table(B)[A]
    assert (next_hop, hops) == (A, 1)
    assert seq_a % 2 == 0 and seq_a == net.routers[A].sequence  # A's own, even
    assert all(A not in net.routers[n].table for n in (C, D))
    net.step(4.0)
    for n in (C, D):
        assert net.table(n)[A] == (B, 2, seq_a)
    assert {d: h for d, (_, h, _) in net.table(A).items()} == {B: 1, C: 2, D: 2}


def test_fig39_link_break():
    """Fig. 3.9: B loses D; B sets D and E to inf with odd numbers, then A and C follow."""
    net = Net([A, B, C, D, E], [(A, B), (B, C), (B, D), (D, E)], ITERATION)
    for it in range(4):
        net.step(float(it))
    old = {n: net.table(n) for n in (A, B, C)}
    assert old[A][D][:2] == (B, 2) and old[A][E][:2] == (B, 3)
    net.unlink(B, D)
    t = 4.0
    while all(net.table(B)[d][1] < INFINITE_HOPS for d in (D, E)):
        net.step(t)
        t += 1.0
        assert t < 10.0, 'B never noticed the break'
    # B notices at the tick that finds D silent for longer than the timeout, and the
    # dump of that same tick carries the break to A and C
    assert t - 1.0 == 3.0 + 2.0 + 1.0
    for d in (D, E):
        _, hops, seq = net.table(B)[d]
        assert hops == INFINITE_HOPS and seq % 2 == 1 and seq > old[B][d][2]
        for n in (A, C):
            assert net.table(n)[d] == (B, INFINITE_HOPS, seq)
    assert net.routers[D].reachable() == {E} and net.routers[E].reachable() == {D}
    # the link comes back: even numbers from D and E outbid the breaks everywhere
    net.link(B, D)
    assert _run_until_converged(net, t + 1.0, 1.0, t + 6.0) is not None


# --------------------------------------------------------------------- properties
def _geometric_graph(n: int, seed: int, radius: float = 25.0) -> list[tuple[int, int]]:
    """Random geometric graph: n agents in a square holding about 6 neighbours each."""
    rng = np.random.default_rng(seed)
    side = radius * np.sqrt(np.pi * n / 6.0)
    pts = rng.uniform(0.0, side, (n, 2))
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    return [(i, j) for i in range(n) for j in range(i + 1, n) if d[i, j] < radius]


def _diameter(dist: np.ndarray) -> int:
    finite = dist[np.isfinite(dist)]
    return int(finite.max()) if finite.size else 0


@PROPERTY
@given(st.integers(5, 30), st.integers(0, 10_000))
def test_converged_routes_are_bfs_shortest_paths(n, seed):
    """After convergence hops equal the BFS distance and next hops lead to the destination.

    Triggered updates go out every 0.25 s tick, so news travels a hop per tick: the
    tables are right within (diameter + 1) ticks of the start.
    """
    net = Net(range(n), _geometric_graph(n, seed))
    diameter = _diameter(_bfs(list(range(n)), net.adj))
    t = _run_until_converged(net, 0.0, 0.25, 0.25 * (diameter + 1))
    assert t is not None, _wrong_routes(net, _bfs(list(range(n)), net.adj))[:5]


@PROPERTY
@given(st.integers(6, 30), st.integers(0, 10_000), st.integers(1, 6))
def test_no_loops_after_link_breaks(n, seed, breaks):
    """Random links break; at no tick do next hops loop, and the tables reconverge.

    A break is noticed after the 2 s neighbour timeout (plus one 0.5 s heartbeat), then
    news travels a hop per 0.25 s tick.
    """
    edges = _geometric_graph(n, seed)
    net = Net(range(n), edges)
    assert _run_until_converged(net, 0.0, 0.25, 20.0) is not None
    rng = np.random.default_rng(seed)
    for k in rng.permutation(len(edges))[:breaks]:
        net.unlink(*edges[k])
    diameter = _diameter(_bfs(list(range(n)), net.adj))
    t, converged = 20.25, None
    while t <= 20.25 + 2.5 + 0.25 * (diameter + 2):
        net.step(t)
        for i in range(n):
            for j in range(n):
                if i != j:
                    _walk(net, i, j)  # raises on a loop
        if converged is None and not _wrong_routes(net, _bfs(list(range(n)), net.adj)):
            converged = t
        t += 0.25
    assert converged is not None, _wrong_routes(net, _bfs(list(range(n)), net.adj))[:5]
    assert not _wrong_routes(net, _bfs(list(range(n)), net.adj))  # and it stays right


def test_converges_with_20_percent_loss():
    """20 % of frames lost per receiver (seeded): the tables still converge, and stay.

    Without loss news travels a hop per 0.25 s tick; a lost frame is repeated at the
    latest by the next full dump (2 s), so a hop costs at most about one dump period:
    the bound is the diameter in periods. Once converged, damping keeps newer numbers
    that arrive over longer paths first from making routes flap (without it about 5 %
    of the routes were longer than the shortest path at any time).
    """
    n, seed = 30, 7
    net = Net(range(n), _geometric_graph(n, seed), loss=0.2, rng=np.random.default_rng(seed))
    dist = _bfs(list(range(n)), net.adj)
    diameter = _diameter(dist)
    period = net.routers[0].config.full_dump_period_s
    t = _run_until_converged(net, 0.0, 0.25, 60.0)
    assert t is not None
    print(f'\n20 % loss: {n} agents, diameter {diameter}: converged at t={t:.2f} s '
          f'= {t / period:.2f} full-dump periods')
    assert t / period <= diameter
    wrong = []
    for k in range(1, 241):  # one more minute
        net.step(t + 0.25 * k)
        wrong.append(len(_wrong_routes(net, dist)))
    share = np.mean(wrong) / (n * (n - 1))
    print(f'20 % loss: over the next 60 s {100 * share:.3f} % of routes not shortest')
    assert share < 0.01


# --------------------------------------------------------------------- data plane
def _chain(n: int, config: DsdvConfig | None = None) -> Net:
    net = Net(range(n), [(i, i + 1) for i in range(n - 1)], config or ITERATION)
    for it in range(n + 1):
        net.step(float(it))
    return net


def test_multihop_unicast_along_next_hops():
    net = _chain(5)
    out = net.routers[0].send(10.0, 4, b'hello')
    assert [p.destination for p in out] == [1]
    net.transmit(10.0, 0, out)
    assert [d.payload for d in net.delivered[4] if d.kind == Kind.DATA] == [b'hello']
    assert net.delivered[4][-1].origin == 0
    assert [net.routers[i].stats.get('forwarded', 0) for i in range(5)] == [0, 1, 1, 1, 0]
    assert all(d.kind != Kind.DATA for i in range(4) for d in net.delivered[i])


@pytest.mark.parametrize(('ttl', 'arrives'), [(4, True), (3, False)])
def test_unicast_ttl_counts_hops(ttl, arrives):
    """A frame crossing 4 links needs TTL 4; with 3 the last relay drops it."""
    net = _chain(5, DsdvConfig(heartbeat_period_s=1.0, full_dump_period_s=1.0,
                               neighbour_timeout_s=2.0, default_ttl=ttl))
    net.transmit(10.0, 0, net.routers[0].send(10.0, 4, b'x'))
    got = [d for d in net.delivered[4] if d.kind == Kind.DATA]
    assert bool(got) is arrives
    assert net.routers[3].stats.get('dropped_ttl', 0) == (0 if arrives else 1)


def test_unicast_without_route_is_counted_not_sent():
    net = _chain(3)
    assert net.routers[0].send(10.0, 99, b'x') == []
    assert net.routers[0].stats['no_route'] == 1


def test_broadcast_flood_delivered_once_everywhere():
    """A flood over a 4x4 grid (many cycles): one delivery per agent, duplicates dropped."""
    ids = range(16)
    edges = [(i, i + 1) for i in ids if i % 4 != 3] + [(i, i + 4) for i in ids if i < 12]
    net = Net(ids, edges, ITERATION)
    net.transmit(0.0, 5, net.routers[5].broadcast(0.0, b'shape v2'))
    for i in ids:
        floods = [d for d in net.delivered[i] if d.kind == Kind.FLOOD]
        assert floods == ([] if i == 5 else [Delivered(5, Kind.FLOOD, b'shape v2')])
    # every agent relays once; every further copy it hears is a duplicate
    assert sum(net.routers[i].stats.get('forwarded', 0) for i in ids) == 15
    heard = sum(len(net.adj[i]) for i in ids)  # each of 16 senders reaches its neighbours
    assert sum(net.routers[i].stats.get('duplicates', 0) for i in ids) == heard - 15


@pytest.mark.parametrize('size', [wire.MAX_WHOLE, wire.MAX_WHOLE + 1, 1000])
def test_fragmented_unicast_and_flood_reassembled(size):
    """Payloads over one frame body go as fragments and arrive whole."""
    payload = bytes(np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8))
    net = _chain(4)
    out = net.routers[0].send(10.0, 3, payload)
    frames = 1 if size <= wire.MAX_WHOLE else -(-size // wire.MAX_CHUNK)
    assert len(out) == frames and all(len(p.payload) <= MAX_BODY for p in out)
    net.transmit(10.0, 0, out)
    assert [d.payload for d in net.delivered[3] if d.kind == Kind.DATA] == [payload]
    net.transmit(11.0, 0, net.routers[0].broadcast(11.0, payload))
    for i in (1, 2, 3):
        assert [d.payload for d in net.delivered[i] if d.kind == Kind.FLOOD] == [payload]


def test_routers_completing_one_message_share_it_and_only_it():
    """Routers of a process that reassemble the same message get one Delivered (its
    decoding is then done once); a later message under the same fragment key, with
    other bytes, is delivered as itself."""
    net = _chain(4)
    first = bytes(range(200))
    net.transmit(10.0, 0, net.routers[0].broadcast(10.0, first))
    got = [[d for d in net.delivered[i] if d.kind == Kind.FLOOD] for i in (1, 2, 3)]
    assert all(len(g) == 1 and g[0].payload == first for g in got)
    assert got[0][0] is got[1][0] is got[2][0]
    # A restarted origin numbers its messages from the start again: the same keys.
    net.routers[0]._frag_id = net.routers[0]._flood_id = 0
    second = bytes(reversed(range(200)))
    for router in (net.routers[i] for i in (1, 2, 3)):
        router._floods.memory[router.route_table.row] = 0    # forget the old copies
    net.transmit(20.0, 0, net.routers[0].broadcast(20.0, second))
    assert [[d.payload for d in net.delivered[i] if d.kind == Kind.FLOOD][-1]
            for i in (1, 2, 3)] == [second] * 3


def test_fragments_out_of_order_and_incomplete():
    """Fragments reassemble in any order; an incomplete message expires, never delivered."""
    net = _chain(2)
    payload = bytes(range(250))
    out = net.routers[0].send(10.0, 1, payload)
    assert len(out) == -(-250 // wire.MAX_CHUNK) == 4   # 74 bytes of message a fragment
    net.transmit(10.0, 0, out[::-1])
    assert net.delivered[1][-1].payload == payload
    count = len(net.delivered[1])
    net.transmit(11.0, 0, net.routers[0].send(11.0, 1, payload)[:2])
    assert len(net.delivered[1]) == count
    timeout = net.routers[1].config.reassembly_timeout_s
    net.routers[1].tick(11.0 + timeout + 0.1)
    assert net.routers[1].stats['fragments_expired'] == 1
