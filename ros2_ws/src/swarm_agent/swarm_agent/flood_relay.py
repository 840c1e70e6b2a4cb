"""Whether a robot relays a flood it heard for the first time (thesis 3.1.2, floods).

Relaying follows the coverage condition of Wu and Dai's generic broadcast scheme (IEEE
Trans. Computers 53(10), 2004) on two-hop knowledge (the one-hop routes in a neighbour's
adverts are its neighbour set): a node stays silent when one connected set of nodes
that are the hop it heard the flood from or higher-id neighbours (they decide the same
way) reaches all its neighbours; this contains self-pruning (Lim and Kim, 2001) and
Rule k (Dai and Wu, 2003). On a connected loss-free network every node gets every flood
(tested in test_flood_pruning).

Against loss a silent node relays anyway with probability k / (its neighbours): each
neighbourhood hears about k extra copies whatever its density (a fixed 15 % share sent 7
extra copies of every cost row around each robot of a 50-robot formation). With
heartbeat loss p, a robot that missed the first copy misses all k(1 - p) others with
probability p^(1 + k(1 - p)); k is the least that keeps this under a target miss
chance, and at least the configured number of copies. On the 50-agent thesis scenario
(seed 0, to settling) self-pruning with a 15 % share delivers 3.99 million frames, this
scheme 1.63 million.

Pure functions of a router's view; ``dsdv.DsdvRouter`` keeps the view and caches the
coverage decision until it changes.
"""

from __future__ import annotations

from collections.abc import Mapping, Set
import functools
import math
import operator
import struct
import zlib


def covered(previous_hop: int, neighbours: Set[int] | int, two_hop: Mapping[int, Set[int]],
            higher: Set[int] | int) -> bool:
    """Do the previous hop and higher-id neighbours, joined up, reach all neighbours?

    ``neighbours``: this node's neighbours; ``two_hop``: each neighbour's advertised
    neighbour set; ``higher``: the neighbours with a higher id than this node whose
    neighbour set is known (each a set or its ``mask``). Checked as: one connected group
    of the previous hop and higher-id neighbours whose closed neighbourhoods contain all
    our neighbours (a few dozen nodes, per view change). The sets are taken as bit masks
    (``mask``): the walk joins a whole neighbourhood in one integer operation, where a
    set union hashes every member.
    """
    sender_reach = two_hop.get(previous_hop)
    if sender_reach is None:
        return False  # the sender's neighbourhood is unknown: relay to be safe
    sender = 1 << previous_hop
    joined = mask(sender_reach)
    need = mask(neighbours) & ~joined & ~sender
    if not need:
        return True   # self-pruning: the sender reached every neighbour of ours
    # Rule k joined with the sender: walk from the sender through higher-id neighbours
    # linked to it until all our neighbours are reached (a group not linked to the
    # sender never helps). A link one side does not advertise yet only makes us relay.
    remaining = mask(higher) & ~sender
    frontier = [previous_hop]
    while frontier:
        linked = mask(two_hop[frontier.pop()]) & remaining
        if linked:
            remaining ^= linked
            joined |= linked
            members = _members(linked)
            for w in members:
                joined |= mask(two_hop[w])
            if not need & ~joined:
                return True
            frontier.extend(members)
    return False


class Neighbourhood(frozenset):
    """A neighbour's advertised neighbour set as a router holds it (immutable, shared
    by the receivers that learnt the same: ``dsdv_receive``), its ``mask`` kept."""

    __slots__ = ('_bits',)


def mask(ids: Set[int] | int) -> int:
    """``ids`` (addresses, 0..65534) as the bits of one integer, bit i for address i (a
    mask is its own; a ``Neighbourhood`` keeps its). Written here because no library
    gives set algebra on a few dozen small integers cheaper than Python's own integers."""
    if ids.__class__ is int:
        return ids
    kept = ids.__class__ is Neighbourhood
    if kept:
        try:
            return ids._bits
        except AttributeError:
            pass
    bits = functools.reduce(operator.or_, map(_ONE.__lshift__, ids), 0)
    if kept:
        ids._bits = bits
    return bits


_ONE = 1


def _members(bits: int) -> list[int]:
    """The addresses whose bits are set, lowest first."""
    out = []
    while bits:
        low = bits & -bits
        out.append(low.bit_length() - 1)
        bits ^= low
    return out


def extra_copies(least: float, loss: float, miss_target: float) -> float:
    """k (module docstring) for the heartbeat loss ``loss`` heard now: at least ``least``
    (0 turns the redundancy off), and enough that a robot misses one flood hop with
    probability under ``miss_target``."""
    if least <= 0.0 or loss <= 0.0:
        return least
    p = min(loss, 0.9)
    return max(least, (math.log(miss_target) / math.log(p) - 1.0) / (1.0 - p))


def relays_anyway(copies: float, neighbours: int, flood_id: int, origin: int,
                  node_id: int) -> bool:
    """A covered node's loss-redundancy relay: with probability copies / neighbours,
    drawn deterministically per (flood, node), so every run decides the same."""
    if copies <= 0.0:
        return False
    fraction = copies / max(neighbours, 1)
    draw = zlib.crc32(_DRAW.pack(flood_id, origin, node_id))
    return draw < fraction * 0xFFFFFFFF


_DRAW = struct.Struct('<HHH')    # the draw's bytes: flood id, origin, node (16 bits each)
