"""One radio frame heard by the DSDV routers of a process (``dsdv``): checked and
decoded once, then applied to every receiver.

A transmission reaches every robot in range (thesis 3.1.2). What depends on the frame
alone (its checks, kind and decoding) is done once; what each router holds is updated
for all receivers of one store in one call of its kernel (``neighbour_table``,
``route_table``): the neighbour heard, link addition, the selection rules. A flood's
first copies are decoded once, and each receiver decides for itself whether to relay.
A router alone in its process (``DsdvRouter.on_packet``) runs the same code with one
receiver. Outputs are read-only and may be shared between receivers: a heartbeat's for
all of them, a flood's for those that relay nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, TYPE_CHECKING

import numpy as np

from swarm_agent import neighbour_table, route_table, wire
from swarm_agent.flood_relay import Neighbourhood
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.route_table import RouteStore, SEQUENCE_STEP
from swarm_agent.wire import WireError

if TYPE_CHECKING:
    from swarm_agent.dsdv import DsdvConfig, DsdvRouter

_KINDS = {int(k): k for k in Kind}
# Compared by identity in ``hear`` (an Enum attribute lookup per frame adds up).
_HEARTBEAT, _FULL, _INCREMENTAL = Kind.HEARTBEAT, Kind.DSDV_FULL, Kind.DSDV_INCREMENTAL
_DATA, _FLOOD = Kind.DATA, Kind.FLOOD


@dataclass(frozen=True)
class Delivered:
    """An application payload for this agent: heartbeat info, routed data or a flood."""

    origin: int
    kind: int
    payload: bytes


@dataclass
class RouterOutput:
    """What one received packet causes: frames to send and payloads for the app."""

    packets: list[Packet] = field(default_factory=list)
    delivered: list[Delivered] = field(default_factory=list)


_NOTHING = RouterOutput()   # what most frames cause: one shared, read-only instance


class Takers(NamedTuple):
    """Routers that hear frames together, with what ``hear`` asks of them worked out
    once (``takers_of``): their addresses and their kernel groups (``_groups``)."""

    ids: frozenset[int]
    groups: list[_Group]


def takers_of(routers: Sequence[DsdvRouter]) -> Takers:
    """``Takers`` of ``routers`` (distinct), for every frame they hear together."""
    return Takers(frozenset(r.id for r in routers), _groups(list(routers)))


def hear(t: float, packet: Packet, routers: Sequence[DsdvRouter],
         known: Takers | None = None) -> list[RouterOutput]:
    """One frame heard by each of ``routers`` (the receivers of one transmission in this
    process): what depends on the frame alone (checks, kind and decoding) is done once,
    then each router applies it. Outputs in order, read-only (may be shared). ``known``:
    ``takers_of(routers)``, when the caller keeps it."""
    outs = [_NOTHING] * len(routers)
    source = packet.source
    if not 0 <= source < BROADCAST:   # no radio has this address (fuzzing)
        _count_all(routers, 'rejected_bad_source')
        return outs
    destination = packet.destination
    groups = None
    if known is not None and destination == BROADCAST and source not in known.ids:
        taking = list(enumerate(routers))     # every router takes it: the common case
        groups = known.groups
    else:
        taking = [(i, r) for i, r in enumerate(routers)
                  if r.id != source and (destination == BROADCAST or r.id == destination)]
        if len(taking) < len(routers):
            _count_all([r for r in routers if r.id != source and r.id != destination
                        and destination != BROADCAST], 'not_for_me')
        if not taking:
            return outs
    every = len(taking) == len(routers)
    takers = routers if every else [r for _, r in taking]
    kind = _KINDS.get(packet.kind)   # (Kind(...) raising would be 2 % of a composed swarm)
    if packet.ttl <= 0 or kind is None:   # swarm_msgs/RadioPacket: ttl 0 is dropped
        _count_all(takers, 'dropped_ttl' if packet.ttl <= 0 else 'rejected_unknown_kind')
        return outs
    try:
        if kind is _FLOOD:
            key = wire.routed_key(packet.payload)
            # Copies already handled (28 % of an agent's frames in a 50-agent thesis
            # trial) are dropped before any other work, by one kernel call per group.
            first = taking if key is None else _first_copies(
                groups or _groups(takers), key, None if every else taking)
            if first:
                _flood_heard(t, packet, first, outs)
        elif kind is _HEARTBEAT:
            seq, info = wire.decode_heartbeat(packet.payload)
            heartbeat = RouterOutput(delivered=[Delivered(source, Kind.HEARTBEAT, info)])
            groups = groups or _groups(takers)
            _neighbour_heard(groups, t, source, True)
            if every:
                outs = [heartbeat] * len(routers)
            else:
                for i, _ in taking:
                    outs[i] = heartbeat
            _link_added(groups, source, seq)
        elif kind is _FULL or kind is _INCREMENTAL:
            seq, adverts = wire.decode_adverts(packet.payload)
            rows, ones, others = _dump_terms(source, adverts)
            groups = groups or _groups(takers)
            _neighbour_heard(groups, t, source, False)
            _learn_neighbourhood(takers, source, ones, others)
            _link_added(groups, source, None, seq)
            _merged(groups, source, rows)
        elif kind is _DATA:
            for i, r in taking:
                outs[i] = _per_router(r, t, packet, kind, r._on_data)
        else:   # a known kind with no handler (FRAGMENT travels inside DATA and FLOOD)
            _count_all(takers, 'rejected_unknown_kind')
    except WireError as exc:
        # The frame's own decoding failed: the same for every receiver.
        for _, r in taking:
            r._malformed(kind, source, exc)
    return outs


def _flood_heard(t: float, packet: Packet, first: list[tuple[int, DsdvRouter]],
                 outs: list[RouterOutput]) -> None:
    """A flood heard for the first time by each router of ``first`` (position in
    ``outs``, router; they remembered it: ``_first_copies``): each takes its message and
    relays it or not; the frame is decoded once, and a whole message is one
    ``Delivered`` for all of them."""
    try:
        origin, flood_id, chunk = wire.decode_routed(packet.payload)
    except WireError as exc:
        for _, r in first:
            r._malformed(_FLOOD, packet.source, exc)
        return
    try:
        message, frag = wire.parse_chunk(chunk)
    except WireError as exc:
        for _, r in first:
            r._malformed(_FLOOD, packet.source, exc)
        return
    whole = [Delivered(origin, Kind.FLOOD, message)] if frag is None else None
    silent = RouterOutput(delivered=whole) if whole is not None else _NOTHING
    for i, r in first:
        if whole is not None:
            r._count('delivered')
            delivered = whole
        else:
            piece = r._reassemble(t, origin, Kind.FLOOD, message, frag)
            delivered = [] if piece is None else [piece]
        packets = r._relay(packet, origin, flood_id)
        # Routers that send nothing and got the whole message share one output (their
        # brains then take it together: ``reception``).
        outs[i] = silent if not packets and delivered is whole else RouterOutput(
            packets, delivered)


def _per_router(router: DsdvRouter, t: float, packet: Packet, kind: Kind,
                handle: Callable[[float, Packet, RouterOutput], None]) -> RouterOutput:
    out = RouterOutput()
    try:
        handle(t, packet, out)
    except WireError as exc:
        router._malformed(kind, packet.source, exc)
    return out


def _count_all(routers: Sequence[DsdvRouter], key: str) -> None:
    for router in routers:
        router._count(key)


class _Group(NamedTuple):
    """Receivers of one frame that share a store and the settings the kernels take as
    scalars (heartbeat timing, damping), with their rows in it."""

    routers: list[DsdvRouter]
    store: RouteStore
    rows: np.ndarray
    positions: list[int]     # of the routers in the list the groups were made of


_ALONE = [0]     # the positions of a router alone (read only)


def _groups(routers: list[DsdvRouter]) -> list[_Group]:
    """``routers`` grouped for the kernels: one group in a process whose routers share a
    store and settings (the evaluator's, a composed container's), once per frame."""
    if len(routers) == 1:   # a node's router, the mission's: one frame at a time
        return [_Group(routers, routers[0].route_table.store, routers[0]._row, _ALONE)]
    token = routers[0]._group       # one store and the same scalar settings
    if all(r._group is token for r in routers):
        split = [list(range(len(routers)))]
    else:
        keyed: dict[object, list[int]] = {}
        for i, r in enumerate(routers):
            keyed.setdefault(r._group, []).append(i)
        split = list(keyed.values())
    groups = []
    for positions in split:
        group = [routers[i] for i in positions]
        groups.append(_Group(group, group[0].route_table.store, np.array(
            [r.route_table.row for r in group], dtype=np.int64), positions))
    return groups


def _first_copies(groups: list[_Group], key: tuple[int, int],
                  taking: list[tuple[int, DsdvRouter]] | None) -> list[tuple[int, DsdvRouter]]:
    """The receivers that handle the flood ``key`` first (``flood_memory``), as
    (position in the outputs, router): the groups' positions are those of ``taking``
    (None: the outputs' own)."""
    first = []
    for routers, store, rows, positions in groups:
        fresh = store.floods.first_copies(rows, key)
        if len(routers) == 1:      # a router alone (a node's, the mission's)
            if fresh[0]:
                first.append((positions[0] if taking is None else taking[positions[0]][0],
                              routers[0]))
            continue
        for j in np.flatnonzero(fresh).tolist():
            p = positions[j]
            first.append((p if taking is None else taking[p][0], routers[j]))
    return first


def scalar_settings(config: DsdvConfig) -> tuple[float, float, int]:
    """The settings the kernels take as scalars, alike in one group of receivers (a
    router's token in its store, ``AddressGrid.group``)."""
    return config.heartbeat_period_s, config.loss_memory, config.stale_generations


def _neighbour_heard(groups: list[_Group], t: float, neighbour: int, beat: bool) -> None:
    """``neighbour`` heard directly by every receiver, in a heartbeat (``beat``) or a
    dump: ``neighbour_table.heard``."""
    for routers, store, rows, _ in groups:
        config = routers[0].config
        for i in neighbour_table.heard(store.neighbours, rows, neighbour, t, beat,
                                       config.heartbeat_period_s,
                                       config.loss_memory).tolist():
            routers[i]._new_neighbour(t)


def _link_added(groups: list[_Group], neighbour: int, seq: int | None,
                dump_seq: int = 0) -> None:
    """Link addition (Fig. 3.8) at every receiver: ``route_table.heard``."""
    for routers, store, rows, _ in groups:
        for i in route_table.heard(store, rows, neighbour, seq, dump_seq).tolist():
            routers[i]._dirty = True


def _merged(groups: list[_Group], neighbour: int, adverts: np.ndarray) -> None:
    """The selection rules (3.1.2.1) at every receiver: ``route_table.merge``."""
    for routers, store, rows, _ in groups:
        changed, damping, damped = route_table.merge(
            store, rows, routers[0].config.stale_generations * SEQUENCE_STEP, neighbour,
            adverts)
        for i in changed.tolist():
            routers[i]._dirty = True
        for i, n in zip(damping.tolist(), damped.tolist()):
            routers[i]._count('damped', n)


_NO_NEIGHBOURS = Neighbourhood()
# Per neighbour address: how many times a router of this process changed, added or
# dropped what it knows of that neighbour's neighbours (``two_hop``).
_EDITS: dict[int, int] = {}
# (identity of a receiver list, neighbour) -> (the list, kept alive so that its id is
# not reused; what all of them and what any of them knew of the neighbour after its last
# dump there; _EDITS of the neighbour then). While no router's knowledge of the
# neighbour has changed since, each of them still holds the first and no more than the
# second.
_LEARNT: dict[tuple[int, int], tuple[Sequence[DsdvRouter], frozenset[int], frozenset[int],
                                     int]] = {}
_LEARNT_LIMIT = 4096


def forget_neighbourhood(router: DsdvRouter, neighbour: int) -> None:
    """The router no longer knows the neighbour's neighbours (its link broke)."""
    if router.two_hop.pop(neighbour, None) is not None:
        _EDITS[neighbour] = _EDITS.get(neighbour, 0) + 1


def _learn_neighbourhood(routers: Sequence[DsdvRouter], neighbour: int, ones: frozenset[int],
                         others: frozenset[int]) -> None:
    """A neighbour's one-hop adverts are its neighbour set (for flood pruning), learnt by
    every receiver: ``ones`` it advertises at one hop are added to what the receiver
    knows of it, ``others`` (at more hops) taken out; a receiver whose knowledge changed
    renews its relay decisions. Each receiver's knowledge is an immutable set, so the
    receivers that knew the same set (most of them) share one result, computed once
    per frame. When nothing changed what the receivers of a list know of the neighbour
    since its last dump to them, and all of them already hold its one-hop adverts and
    none of its others (a neighbour's dumps mostly repeat), none of them is visited."""
    key = (id(routers), neighbour)
    edits = _EDITS.get(neighbour, 0)
    last = _LEARNT.get(key)
    if (last is not None and last[0] is routers and last[3] == edits
            and ones <= last[1] and last[2].isdisjoint(others)):
        return    # what each receiver knows already holds ones and none of the others
    # id of a known set -> (the set, kept alive so its id is not reused; what it becomes)
    outcome: dict[int, tuple[frozenset[int], frozenset[int]]] = {}
    seen = learnt = None      # the set the previous receiver knew: most follow it
    for r in routers:
        two_hop = r.two_hop
        known = two_hop.get(neighbour)
        if known is None:
            known = two_hop[neighbour] = _NO_NEIGHBOURS
            r._known_grew = True     # its relay decisions' higher-id set may grow
            edits += 1
        if known is not seen:
            seen = known
            _, learnt = outcome.get(id(known)) or (None, None)
            if learnt is None:
                learnt = (known if ones <= known and known.isdisjoint(others)
                          else Neighbourhood((known | ones) - others))
                outcome[id(known)] = (known, learnt)
        if learnt is not known:
            two_hop[neighbour] = learnt
            r._neighbourhood_changed(neighbour)
            edits += 1
    _EDITS[neighbour] = edits
    if len(_LEARNT) >= _LEARNT_LIMIT:
        _LEARNT.clear()
    learnt_sets = [s for _, s in outcome.values()]
    if len(learnt_sets) == 1:   # all of them know one set (a router alone: always)
        _LEARNT[key] = (routers, learnt_sets[0], learnt_sets[0], edits)
    else:
        _LEARNT[key] = (routers, frozenset.intersection(*learnt_sets),
                        frozenset.union(*learnt_sets), edits)


def _dump_terms(neighbour: int, adverts: np.ndarray) -> tuple[
        np.ndarray, frozenset[int], frozenset[int]]:
    """What every receiver of a neighbour's dump reads, once per frame: the adverts, the
    (k, 3) array the route table's kernel reads (``wire.decode_adverts``), the
    destinations the neighbour advertises at one hop (its neighbours) and those at more
    (not its neighbours; itself excepted). A destination advertised both ways in one
    frame counts as a neighbour. The results of the last frames are kept by the identity
    of ``adverts`` (one per frame content), for the mission's radio, which
    hears a step's frames before the robots do."""
    kept = _TERMS.get(id(adverts))
    if kept is not None and kept[0] is adverts and kept[1] == neighbour:
        return kept[2]
    destinations = adverts[:, 0]
    one = adverts[:, 1] == 1
    ones = frozenset(destinations[one].tolist())
    others = frozenset(destinations[~one & (destinations != neighbour)].tolist())
    terms = adverts, ones, others - ones
    if len(_TERMS) >= 256:
        _TERMS.clear()
    _TERMS[id(adverts)] = (adverts, neighbour, terms)   # referenced: its id is not reused
    return terms


# id(adverts) -> (adverts, neighbour, _dump_terms of them)
_TERMS: dict[int, tuple[np.ndarray, int, tuple[np.ndarray, frozenset[int],
                                              frozenset[int]]]] = {}
