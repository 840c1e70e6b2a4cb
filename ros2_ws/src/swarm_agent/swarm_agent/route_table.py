"""The route table of one DSDV router as arrays, and the selection rules as kernels.

A row per destination ever heard (rows are never removed: a lost route is kept with an
infinite metric and an odd sequence number, thesis 3.1.2.3):

    rows[r] = (destination, sequence number, hops, next hop, changed)

``slot[destination]`` is the row of a destination (-1: none), for every 16-bit address,
so a kernel finds a row with one read. The rules that run for every advert of every dump
every receiver hears (a tenth of a 50-agent trial as dict lookups and attribute writes)
run as compiled loops over these arrays (``swarm_common.jit``); the rules that run a few
times a second per router (dumps, link breaks) are numpy on the rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_agent.wire import INFINITE_HOPS
from swarm_common.jit import kernel

SEQUENCE_STEP = 2           # own sequence numbers grow by this at every full dump (even)
SEQUENCE_MASK = 0xFFFFFFFF  # sequence numbers are 32-bit on the wire and wrap around
HALF = 1 << 31
ADDRESSES = 1 << 16
DEST, SEQ, HOPS, NEXT, CHANGED = range(5)   # columns of ``rows``


@dataclass
class RouteEntry:
    """One row of the route table (swarm_msgs/RouteEntry)."""

    destination: int
    next_hop: int
    hop_count: int
    sequence_number: int
    changed: bool = True


class RouteTable:
    """Destination -> (next hop, hops, sequence number, changed); see the module."""

    def __init__(self, capacity: int = 16) -> None:
        self.slot = np.full(ADDRESSES, -1, dtype=np.int32)
        self.rows = np.zeros((capacity, 5), dtype=np.int64)
        self.count = 0

    def __len__(self) -> int:
        return self.count

    def reserve(self, extra: int) -> None:
        """Room for ``extra`` more rows (a kernel adds rows but does not grow arrays)."""
        need = self.count + extra
        if need > len(self.rows):
            grown = np.zeros((max(need, 2 * len(self.rows)), 5), dtype=np.int64)
            grown[:self.count] = self.rows[:self.count]
            self.rows = grown

    def get(self, destination: int) -> RouteEntry | None:
        """The row of ``destination`` as a RouteEntry (a copy), or None."""
        r = int(self.slot[destination]) if 0 <= destination < ADDRESSES else -1
        if r < 0:
            return None
        d, seq, hops, nxt, changed = self.rows[r].tolist()
        return RouteEntry(d, nxt, hops, seq, bool(changed))

    def set(self, entry: RouteEntry) -> None:
        """Write one row (a new destination gets a new row)."""
        r = int(self.slot[entry.destination])
        if r < 0:
            self.reserve(1)
            r = self.slot[entry.destination] = self.count
            self.count += 1
        self.rows[r] = (entry.destination, entry.sequence_number & SEQUENCE_MASK,
                        entry.hop_count, entry.next_hop, int(entry.changed))

    def entries(self) -> list[RouteEntry]:
        """Every row as a RouteEntry, sorted by destination (copies)."""
        rows = self.rows[:self.count]
        return [RouteEntry(d, nxt, hops, seq, bool(changed))
                for d, seq, hops, nxt, changed in rows[np.argsort(rows[:, DEST])].tolist()]

    def next_hop(self, destination: int) -> int | None:
        r = self.slot[destination] if 0 <= destination < ADDRESSES else -1
        if r < 0:
            return None
        row = self.rows[r]
        return int(row[NEXT]) if row[HOPS] < INFINITE_HOPS else None

    def reachable(self) -> set[int]:
        rows = self.rows[:self.count]
        return set(rows[rows[:, HOPS] < INFINITE_HOPS, DEST].tolist())

    def any_changed(self) -> bool:
        return bool(self.rows[:self.count, CHANGED].any())

    def clear_changed(self) -> None:
        self.rows[:self.count, CHANGED] = 0

    def changed_entries(self) -> list[RouteEntry]:
        return [e for e in self.entries() if e.changed]

    def break_link(self, neighbour: int) -> bool:
        """Fig. 3.9: every finite route through ``neighbour`` gets hops = inf and the next
        odd sequence number (one above an even number, two above an odd one). Returns
        whether any route changed."""
        rows = self.rows[:self.count]
        hit = (rows[:, NEXT] == neighbour) & (rows[:, HOPS] < INFINITE_HOPS)
        if not hit.any():
            return False
        seq = rows[hit, SEQ]
        rows[hit, SEQ] = (seq + 1 + (seq & 1)) & SEQUENCE_MASK
        rows[hit, HOPS] = INFINITE_HOPS
        rows[hit, CHANGED] = 1
        return True

    def heard(self, neighbour: int, seq: int, dump_seq: int) -> bool:
        """Link addition (``DsdvRouter._heard``; ``seq`` < 0: heard in a dump whose header
        number is ``dump_seq``). Returns whether the table changed."""
        self.reserve(1)
        changed, count = _heard(self.slot, self.rows, self.count, neighbour, seq, dump_seq)
        self.count = int(count)
        return bool(changed)

    def merge(self, own: int, own_sequence: int, stale: int, neighbour: int,
              adverts: np.ndarray) -> tuple[int, bool, int]:
        """The selection rules on a neighbour's adverts (``DsdvRouter._merge``): (own
        sequence number, table changed, adverts damped)."""
        self.reserve(len(adverts))
        own_sequence, dirty, damped, count = _merge(
            self.slot, self.rows, self.count, own, own_sequence, stale, neighbour, adverts)
        self.count = int(count)
        return int(own_sequence), bool(dirty), int(damped)


def seq_newer(a: int, b: int) -> bool:
    """Serial-number order (RFC 1982) of 32-bit sequence numbers: is ``a`` newer than ``b``?

    Plain ``>`` breaks at the wrap: one advert with 0xFFFFFFFF (a fuzzing input, in
    tests/data/fuzz_corpus) would make a destination unreachable for good, since its
    real, wrapped numbers would look older.
    """
    return 0 < ((a - b) & SEQUENCE_MASK) < HALF


_EXAMPLE = (np.full(ADDRESSES, -1, np.int32), np.zeros((4, 5), np.int64), 0)


@kernel(*_EXAMPLE, 3, 6, 4)
def _heard(slot: np.ndarray, rows: np.ndarray, count: int, neighbour: int, seq: int,
           dump_seq: int) -> tuple[bool, int]:
    """Link addition (Fig. 3.8): a neighbour heard directly is a one-hop route.

    A heartbeat carries the neighbour's own (even) sequence number ``seq``. If we had
    marked the route broken (odd number), the direct link is proof enough: the route is
    restored with the next even number, which outbids the break. A dump heard first
    (``seq`` < 0) makes the route a step below the sender's own number ``dump_seq`` (its
    header), older than its next heartbeat (a fixed 0 could be newer than a boot number).
    Returns (table changed, rows in use); ``rows`` has room for one more.
    """
    r = slot[neighbour]
    if seq < 0:
        if r >= 0:
            return False, count
        best = (dump_seq - SEQUENCE_STEP) & SEQUENCE_MASK
    else:
        if r >= 0:
            ahead = (seq - rows[r, SEQ]) & SEQUENCE_MASK
            if rows[r, HOPS] == 1 and rows[r, NEXT] == neighbour and not 0 < ahead < HALF:
                return False, count
            restored = (rows[r, SEQ] + (rows[r, SEQ] & 1)) & SEQUENCE_MASK
            best = restored if 0 < ((restored - seq) & SEQUENCE_MASK) < HALF else seq
        else:
            best = seq
    if r < 0:
        r = slot[neighbour] = count
        count += 1
    rows[r, DEST], rows[r, SEQ], rows[r, HOPS] = neighbour, best, 1
    rows[r, NEXT], rows[r, CHANGED] = neighbour, 1
    return True, count


@kernel(*_EXAMPLE, 7, 10, 12, 3, np.array([[5, 1, 8], [7, 0, 4]], dtype=np.int64))
def _merge(slot: np.ndarray, rows: np.ndarray, count: int, own: int, own_sequence: int,
           stale: int, neighbour: int, adverts: np.ndarray) -> tuple[int, bool, int, int]:
    """Apply the two selection rules (3.1.2.1) to a neighbour's ``adverts`` (k, 3:
    destination, hops as advertised, sequence number).

    A newer sequence number always wins; with the same number a shorter path wins. A
    newer broken-link advert (infinite hops) invalidates the route (Fig. 3.9). Damping:
    a newer number first heard over a longer path from another neighbour is ignored
    unless the route is broken or ``stale`` numbers behind (the shorter path brings it
    soon; ignoring an advert is the same as losing it, so loop freedom is kept). Only a
    new metric marks a route changed (a triggered update); a newer number alone waits
    for the next full dump (DSDV's settling rule, Perkins and Bhagwat 1994). An advert
    of ourselves with a newer (odd, broken) number is outbid. Returns (own sequence
    number, table changed, adverts damped, rows in use); ``rows`` has room for k more.
    """
    dirty = False
    damped = 0
    for k in range(adverts.shape[0]):
        dest, hops, sequence = adverts[k, 0], adverts[k, 1], adverts[k, 2]
        if dest == own:
            if 0 < ((sequence - own_sequence) & SEQUENCE_MASK) < HALF:
                own_sequence = (sequence + (1 if sequence % 2 else 2)) & SEQUENCE_MASK
            continue
        hops = INFINITE_HOPS if hops >= INFINITE_HOPS - 1 else hops + 1
        r = slot[dest]
        if r < 0:
            if hops < INFINITE_HOPS:
                r = slot[dest] = count
                count += 1
                rows[r, DEST], rows[r, SEQ], rows[r, HOPS] = dest, sequence, hops
                rows[r, NEXT], rows[r, CHANGED] = neighbour, 1
                dirty = True
            continue
        ahead = (sequence - rows[r, SEQ]) & SEQUENCE_MASK
        if ahead == 0:
            if hops >= rows[r, HOPS]:
                continue                    # same number, no shorter path
        elif ahead >= HALF:
            continue                        # older than what we hold
        elif hops >= INFINITE_HOPS:
            rows[r, HOPS], rows[r, SEQ], rows[r, CHANGED] = INFINITE_HOPS, sequence, 1
            dirty = True
            continue
        elif not (rows[r, NEXT] == neighbour or hops <= rows[r, HOPS]
                  or rows[r, HOPS] >= INFINITE_HOPS or ahead >= stale):
            damped += 1
            continue
        if rows[r, HOPS] != hops:
            rows[r, CHANGED] = 1
            dirty = True
        rows[r, NEXT], rows[r, HOPS], rows[r, SEQ] = neighbour, hops, sequence
    return own_sequence, dirty, damped, count
