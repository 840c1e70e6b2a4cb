"""``dsdv_receive.hear``: one frame applied to several routers at once is the same as
applying it to each (``DsdvRouter.on_packet``), for every kind of frame and every way it
fails."""

from __future__ import annotations

import copy

import pytest

from swarm_agent.dsdv import DsdvRouter
from swarm_agent.dsdv_receive import hear, takers_of
from swarm_agent.packet import BROADCAST, Kind, Packet


def _mesh() -> list[DsdvRouter]:
    """Five routers 1-5 in a line, run 6 s, so tables, neighbour sets and floods exist."""
    routers = [DsdvRouter(i) for i in range(1, 6)]
    t = 0.0
    while t < 6.0:
        for k, router in enumerate(routers):
            for packet in router.tick(t):
                for j in (k - 1, k + 1):
                    if 0 <= j < len(routers):
                        routers[j].on_packet(t, packet)
        t += 0.1
    return routers


def _state(router: DsdvRouter):
    return (router.sequence, {d: vars(r) for d, r in router.table.items()},
            dict(router.heard), {k: set(v) for k, v in router.two_hop.items()},
            dict(router.stats), router.remembered())


FRAMES = {
    'heartbeat': lambda r: r[2].tick(10.0)[0],                        # from router 3
    'full dump': lambda r: [p for p in r[2].tick(10.0) if p.kind == Kind.DSDV_FULL][0],
    'flood': lambda r: r[0].broadcast(6.0, b'row' * 40)[0],            # fragmented
    'flood copy': lambda r: r[1].broadcast(6.0, b'x')[0],
    'data for 4': lambda r: r[2].send(6.0, 4, b'hello')[0],
    'own frame': lambda r: r[1].tick(10.0)[0],                        # 2 hears itself
    'fragment kind': lambda r: Packet(3, BROADCAST, int(Kind.FRAGMENT), 1, 1, b'\0' * 8),
    'bad source': lambda r: Packet(BROADCAST, BROADCAST, int(Kind.HEARTBEAT), 1, 1, b''),
    'ttl 0': lambda r: Packet(3, BROADCAST, int(Kind.HEARTBEAT), 1, 0, b'\0' * 4),
    'unknown kind': lambda r: Packet(3, BROADCAST, 9, 1, 1, b'\0' * 8),
    'malformed dump': lambda r: Packet(3, BROADCAST, int(Kind.DSDV_FULL), 1, 1, b'\2\0'),
    'malformed flood': lambda r: Packet(3, BROADCAST, int(Kind.FLOOD), 1, 1, b'\2\0'),
}


@pytest.mark.parametrize('kept', [False, True], ids=['fresh', 'kept takers'])
@pytest.mark.parametrize('name', sorted(FRAMES))
def test_one_call_for_all_receivers_is_one_call_each(name, kept):
    """Also with the receivers' ``Takers`` worked out before the frame (``kept``), as
    a process that keeps them per set of receivers does: a frame one of them sent
    itself ('own frame'), or one for one of them only, is checked as without."""
    mesh = _mesh()
    packet = FRAMES[name](mesh)
    receivers = [mesh[1], mesh[3], mesh[4]]          # 2, 4 and 5
    apart = copy.deepcopy(receivers)
    known = takers_of(receivers) if kept else None
    assert known is None or known.ids == {2, 4, 5}
    before = [_state(r) for r in receivers]
    outs_apart = [r.on_packet(6.5, packet) for r in apart]
    outs = hear(6.5, packet, receivers, known)
    assert len(outs) == 3
    for together, alone, out, out_alone in zip(receivers, apart, outs, outs_apart):
        assert _state(together) == _state(alone)
        assert out.packets == out_alone.packets and out.delivered == out_alone.delivered
    # Each frame did something to some router: learnt, stored, counted or dropped as such.
    assert any(_state(r) != b for r, b in zip(receivers, before))


def test_a_neighbours_dump_tells_its_neighbour_set():
    """One-hop adverts are the sender's neighbours (flood pruning); a destination the
    sender advertises at more hops, or as broken, is not; itself is never one."""
    from swarm_agent.wire import Advert, encode_adverts

    router = DsdvRouter(1)

    def dump(*adverts):
        frame = encode_adverts(10, [Advert(*a) for a in adverts])[0]
        router.on_packet(1.0, Packet(3, BROADCAST, int(Kind.DSDV_FULL), 1, 1, frame))
        return router.two_hop[3]

    assert dump((3, 0, 10), (5, 1, 4), (6, 1, 8), (7, 2, 2)) == {5, 6}
    assert dump((3, 0, 12), (5, 2, 6), (7, 1, 2)) == {6, 7}       # 6 not mentioned: kept
    assert dump((3, 0, 14), (6, 255, 9)) == {7}                   # broken: gone
    # Advertised both ways in one frame (no router sends that): a neighbour.
    assert dump((3, 0, 16), (8, 2, 4), (8, 1, 4)) == {7, 8}


def test_receivers_that_knew_different_neighbour_sets_each_learn_their_own():
    """One dump heard by routers that knew the sender's neighbours differently (the
    receivers of a frame share one result per set they knew): each ends with what it knew
    plus the one-hop adverts less the others; a receiver whose knowledge did not change
    keeps its relay decisions, one whose knowledge of the lower-id sender changed renews
    the one after the sender (the coverage condition reads no other decision's), one
    that learnt of the sender for the first time renews them all."""
    from swarm_agent.wire import Advert, encode_adverts

    routers = [DsdvRouter(i) for i in (1, 2, 4, 5)]
    beat = DsdvRouter(3).tick(0.0)[0]                 # 3 is everyone's neighbour first
    hear(0.5, beat, routers)
    knew = [frozenset({5, 6}), frozenset({5, 6}), frozenset({6, 8, 9}), None]
    for router, known in zip(routers, knew):
        if known is not None:
            router.two_hop[3] = known
        router._silent_after.update({3: True, 7: True})   # relay decisions held
    frame = encode_adverts(10, [Advert(3, 0, 10), Advert(5, 1, 4), Advert(6, 1, 8),
                                Advert(9, 2, 2)])[0]
    hear(1.0, Packet(3, BROADCAST, int(Kind.DSDV_FULL), 1, 1, frame), routers)
    assert [r.two_hop[3] for r in routers] == [{5, 6}, {5, 6}, {5, 6, 8}, {5, 6}]
    assert routers[0].two_hop[3] is knew[0]          # unchanged: the same set
    assert [set(r._silent_after) for r in routers] == [{3, 7}, {3, 7}, {7}, set()]


def test_receivers_that_heard_a_dump_before_learn_again_after_any_change():
    """The receivers of a neighbour's dumps are not visited again while nothing changed
    what they know of it: on a random run of dumps from three neighbours to overlapping
    receiver lists (kept and fresh), with links breaking, every router holds exactly
    what the definition gives: the one-hop adverts added, the others taken out, all
    forgotten when the link breaks."""
    import numpy as np

    from swarm_agent.wire import Advert, encode_adverts

    rng = np.random.default_rng(11)
    routers = {i: DsdvRouter(i) for i in range(1, 9)}
    kept = [[routers[i] for i in ids] for ids in ((1, 2, 3), (2, 3, 4, 5), (6, 7, 8))]
    want: dict[int, dict[int, set[int]]] = {i: {} for i in routers}
    for step in range(400):
        sender = int(rng.choice([20, 21, 22]))
        if rng.random() < 0.1:                       # a link breaks at one receiver
            r = routers[int(rng.integers(1, 9))]
            r._break_link(sender)
            want[r.id].pop(sender, None)
            continue
        heard = (kept[int(rng.integers(0, 3))] if rng.random() < 0.8
                 else [routers[i] for i in sorted(rng.choice(8, 3, replace=False) + 1)])
        adverts = [Advert(sender, 0, 2 * step)] + [
            Advert(int(d), int(rng.choice([1, 1, 2, 255])), 2 * step)
            for d in rng.choice(np.arange(30, 36), int(rng.integers(0, 4)), replace=False)]
        frame = encode_adverts(2 * step, adverts)[0]
        hear(float(step), Packet(sender, BROADCAST, int(Kind.DSDV_FULL), step, 1, frame),
             heard)
        ones = {a.destination for a in adverts[1:] if a.hops == 1}
        others = {a.destination for a in adverts[1:] if a.hops != 1} - ones
        for r in heard:
            want[r.id][sender] = (want[r.id].get(sender, set()) | ones) - others
        for i, r in routers.items():
            assert {k: set(v) for k, v in r.two_hop.items()} == want[i], (step, i)
