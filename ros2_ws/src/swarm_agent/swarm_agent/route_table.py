"""DSDV route tables as arrays, one row per router of a process, and their rules as kernels.

A ``RouteStore`` holds the route tables of every router of a process (the headless
evaluator's swarm, a composed container's agents; a node with one router has a store of
its own): row ``p`` is router p's table, column ``c`` the destination ``ids[c]``
(``column[destination]`` finds it for every 16-bit address), and each cell holds

    cells[p, c] = (sequence number, hops, next hop, changed)    hops -1: no route

Rows are never emptied: a lost route is kept with an infinite metric and an odd sequence
number (thesis 3.1.2.3). A ``RouteTable`` is one router's view (store, row).

The rules that run for every frame every receiver hears (link addition for each
heartbeat and dump, the selection rules for each dump's adverts: a quarter of a 50-agent
trial as dict lookups and attribute writes per receiver) are kernels
(``swarm_common.jit``) applied to all the receivers of one transmission in one call
(``heard``, ``merge``: ``rows`` lists the receivers' rows); the rules that run a few
times a second per router (dumps, link breaks) are numpy on the router's row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarm_agent.address_grid import ADDRESSES, AddressGrid
from swarm_agent.flood_memory import FloodMemory
from swarm_agent.neighbour_table import NeighbourGrid
from swarm_agent.wire import INFINITE_HOPS
from swarm_common.jit import kernel

SEQUENCE_STEP = 2           # own sequence numbers grow by this at every full dump (even)
SEQUENCE_MASK = 0xFFFFFFFF  # sequence numbers are 32-bit on the wire and wrap around
HALF = 1 << 31
SEQ, HOPS, NEXT, CHANGED = range(4)   # fields of a cell
NONE = -1                              # hops of a cell without a route


@dataclass
class RouteEntry:
    """One row of the route table (swarm_msgs/RouteEntry)."""

    destination: int
    next_hop: int
    hop_count: int
    sequence_number: int
    changed: bool = True


def seq_newer(a: int, b: int) -> bool:
    """Serial-number order (RFC 1982) of 32-bit sequence numbers: is ``a`` newer than ``b``?

    Plain ``>`` breaks at the wrap: one advert with 0xFFFFFFFF (a fuzzing input, in
    tests/data/fuzz_corpus) would make a destination unreachable for good, since its
    real, wrapped numbers would look older.
    """
    return 0 < ((a - b) & SEQUENCE_MASK) < HALF


class RouteStore(AddressGrid):
    """The route tables of a process's routers (see the module docstring), their
    neighbour tables (``neighbours``, ``neighbour_table``), row for row, and each
    router's address and own sequence number (``own``, ``own_seq``: the selection rules
    read and outbid them)."""

    def __init__(self) -> None:
        super().__init__((0, NONE, 0, 0), np.int64)
        self.neighbours = NeighbourGrid()
        self.floods = FloodMemory()     # the flood keys each router remembers
        self.own = np.zeros(1, dtype=np.int64)
        self.own_seq = np.zeros(1, dtype=np.int64)

    def add_row(self, address: int = 0) -> int:
        """A new router of radio address ``address``, every route empty; returns its row."""
        row = super().add_row()
        self.neighbours.add_row()
        self.floods.add_row(0)          # its router sets how many it remembers
        if row == len(self.own):
            self.own = np.concatenate([self.own, np.zeros_like(self.own)])
            self.own_seq = np.concatenate([self.own_seq, np.zeros_like(self.own_seq)])
        self.own[row] = address
        return row


class RouteTable:
    """One router's table: destination -> (next hop, hops, sequence number, changed)."""

    def __init__(self, store: RouteStore | None = None, address: int = 0) -> None:
        """The table of the router of radio address ``address`` in ``store`` (None: a
        store of its own)."""
        self.store = store or RouteStore()
        self.row = self.store.add_row(address)

    @property
    def own_sequence(self) -> int:
        """The router's own sequence number."""
        return int(self.store.own_seq[self.row])

    @own_sequence.setter
    def own_sequence(self, sequence: int) -> None:
        self.store.own_seq[self.row] = sequence

    def _cells(self) -> np.ndarray:
        """This table's cells of the columns in use (a view)."""
        return self.store.cells[self.row, :self.store.width]

    def set(self, entry: RouteEntry) -> None:
        """Write one route."""
        c = self.store.column_of(entry.destination)
        self.store.cells[self.row, c] = (entry.sequence_number & SEQUENCE_MASK,
                                         entry.hop_count, entry.next_hop, int(entry.changed))

    def _by_destination(self, changed_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The destinations with a route (those changed only, if asked) in order, and
        their cells."""
        cells = self._cells()
        keep = cells[:, HOPS] != NONE
        if changed_only:
            keep &= cells[:, CHANGED] != 0
        cols = np.flatnonzero(keep)
        cols = cols[np.argsort(self.store.ids[cols])]
        return self.store.ids[cols], cells[cols]

    def entries(self) -> list[RouteEntry]:
        """Every route, sorted by destination (copies)."""
        ids, cells = self._by_destination()
        return [RouteEntry(d, nxt, hops, seq, bool(changed))
                for d, (seq, hops, nxt, changed) in zip(ids.tolist(), cells.tolist())]

    def next_hop(self, destination: int) -> int | None:
        c = self.store.column[destination] if 0 <= destination < ADDRESSES else -1
        if c < 0:
            return None
        hops = self.store.cells[self.row, c, HOPS]
        return int(self.store.cells[self.row, c, NEXT]) if 0 <= hops < INFINITE_HOPS else None

    def reachable(self) -> set[int]:
        hops = self._cells()[:, HOPS]
        return set(self.store.ids[:self.store.width][(hops >= 0) & (hops < INFINITE_HOPS)]
                   .tolist())

    def any_changed(self) -> bool:
        return bool(self._cells()[:, CHANGED].any())

    def clear_changed(self) -> None:
        self._cells()[:, CHANGED] = 0

    def advert_columns(self, changed_only: bool = False) -> tuple[
            np.ndarray, np.ndarray, np.ndarray]:
        """The routes as adverts, sorted by destination: all of them (a full dump) or
        those changed (an incremental one), as three arrays (destinations, hops,
        sequence numbers) for ``wire.encode_advert_columns``."""
        ids, cells = self._by_destination(changed_only)
        return ids, cells[:, HOPS], cells[:, SEQ]

    def break_link(self, neighbour: int) -> bool:
        """Fig. 3.9: every finite route through ``neighbour`` gets hops = inf and the next
        odd sequence number (one above an even number, two above an odd one). Returns
        whether any route changed."""
        cells = self._cells()
        hit = (cells[:, NEXT] == neighbour) & (cells[:, HOPS] >= 0) \
            & (cells[:, HOPS] < INFINITE_HOPS)
        if not hit.any():
            return False
        seq = cells[hit, SEQ]
        cells[hit, SEQ] = (seq + 1 + (seq & 1)) & SEQUENCE_MASK
        cells[hit, HOPS] = INFINITE_HOPS
        cells[hit, CHANGED] = 1
        return True


def heard(store: RouteStore, rows: np.ndarray, neighbour: int, seq: int | None,
          dump_seq: int = 0) -> np.ndarray:
    """Link addition in the tables ``rows`` of ``store`` for ``neighbour`` heard
    directly (``_heard``; ``seq`` None: heard in a dump headed ``dump_seq``). Returns
    the positions in ``rows`` of the tables that changed."""
    col = store.column_of(neighbour)         # may grow the cells: before reading them
    return _heard(store.cells, rows, col, neighbour, -1 if seq is None else seq, dump_seq)


def merge(store: RouteStore, rows: np.ndarray, stale: int, neighbour: int,
          adverts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The selection rules in the tables ``rows`` of ``store`` on ``neighbour``'s
    ``adverts`` (k, 3: destination, hops, sequence number), with the damping horizon
    ``stale`` (``_merge``; the routers' own numbers are outbid in the store). Returns the
    positions in ``rows`` of the tables that changed and of those that damped adverts,
    and how many each of the latter damped."""
    cols = store.columns(adverts[:, 0])      # may grow the cells: before reading them
    return _merge(store.cells, rows, store.own, store.own_seq, stale, neighbour, cols,
                  adverts)


_CELLS = RouteStore().cells
_ROWS = np.zeros(1, dtype=np.int64)


@kernel(_CELLS, _ROWS, 1, 3, 6, 4)
def _heard(cells: np.ndarray, rows: np.ndarray, col: int, neighbour: int, seq: int,
           dump_seq: int) -> np.ndarray:
    """Link addition (Fig. 3.8) in each table of ``rows``: a neighbour heard directly
    (column ``col``) is a one-hop route.

    A heartbeat carries the neighbour's own (even) sequence number ``seq``. If we had
    marked the route broken (odd number), the direct link is proof enough: the route is
    restored with the next even number, which outbids the break. A dump heard first
    (``seq`` < 0) makes the route a step below the sender's own number ``dump_seq`` (its
    header), older than its next heartbeat (a fixed 0 could be newer than a boot number).
    Returns the positions in ``rows`` of the tables that changed.
    """
    changed = np.zeros(rows.shape[0], dtype=np.int64)
    n = 0
    for i in range(rows.shape[0]):
        cell = cells[rows[i], col]
        known = cell[HOPS] != NONE
        if seq < 0:
            if known:
                continue
            best = (dump_seq - SEQUENCE_STEP) & SEQUENCE_MASK
        elif known:
            ahead = (seq - cell[SEQ]) & SEQUENCE_MASK
            if cell[HOPS] == 1 and cell[NEXT] == neighbour and not 0 < ahead < HALF:
                continue
            restored = (cell[SEQ] + (cell[SEQ] & 1)) & SEQUENCE_MASK
            best = restored if 0 < ((restored - seq) & SEQUENCE_MASK) < HALF else seq
        else:
            best = seq
        cell[SEQ], cell[HOPS], cell[NEXT], cell[CHANGED] = best, 1, neighbour, 1
        changed[n] = i
        n += 1
    return changed[:n]


@kernel(_CELLS, _ROWS, np.array([7]), np.array([10]), 12, 3, np.array([0, 1]),
        np.array([[5, 1, 8], [7, 0, 4]], dtype=np.int64))
def _merge(cells: np.ndarray, rows: np.ndarray, own: np.ndarray, own_seq: np.ndarray,
           stale: int, neighbour: int, cols: np.ndarray, adverts: np.ndarray) -> tuple[
               np.ndarray, np.ndarray, np.ndarray]:
    """The two selection rules (3.1.2.1) on a neighbour's ``adverts`` (k, 3: destination,
    hops as advertised, sequence number; destination k in column ``cols[k]``) in each
    table of ``rows``, whose router has the address ``own[row]`` and the own number
    ``own_seq[row]`` (outbid here), with the damping horizon ``stale``.

    A newer sequence number always wins; with the same number a shorter path wins. A
    newer broken-link advert (infinite hops) invalidates the route (Fig. 3.9). Damping:
    a newer number first heard over a longer path from another neighbour is ignored
    unless the route is broken or ``stale`` numbers behind (the shorter path brings it
    soon; ignoring an advert is the same as losing it, so loop freedom is kept). Only a
    new metric marks a route changed (a triggered update); a newer number alone waits
    for the next full dump (DSDV's settling rule, Perkins and Bhagwat 1994). An advert
    of the router itself with a newer (odd, broken) number is outbid. Returns the
    positions in ``rows`` of the tables that changed, of those that damped adverts, and
    how many each of the latter damped.
    """
    n = rows.shape[0]
    dirty = np.zeros(n, dtype=np.bool_)
    damped = np.zeros(n, dtype=np.int64)
    for i in range(n):
        row = rows[i]
        table = cells[row]
        for k in range(adverts.shape[0]):
            dest, hops, sequence = adverts[k, 0], adverts[k, 1], adverts[k, 2]
            if dest == own[row]:
                if 0 < ((sequence - own_seq[row]) & SEQUENCE_MASK) < HALF:
                    own_seq[row] = (sequence + (1 if sequence % 2 else 2)) & SEQUENCE_MASK
                continue
            hops = INFINITE_HOPS if hops >= INFINITE_HOPS - 1 else hops + 1
            cell = table[cols[k]]
            if cell[HOPS] == NONE:
                if hops < INFINITE_HOPS:
                    cell[SEQ], cell[HOPS], cell[NEXT], cell[CHANGED] = \
                        sequence, hops, neighbour, 1
                    dirty[i] = True
                continue
            ahead = (sequence - cell[SEQ]) & SEQUENCE_MASK
            if ahead == 0:
                if hops >= cell[HOPS]:
                    continue                    # same number, no shorter path
            elif ahead >= HALF:
                continue                        # older than what we hold
            elif hops >= INFINITE_HOPS:
                cell[HOPS], cell[SEQ], cell[CHANGED] = INFINITE_HOPS, sequence, 1
                dirty[i] = True
                continue
            elif not (cell[NEXT] == neighbour or hops <= cell[HOPS]
                      or cell[HOPS] >= INFINITE_HOPS or ahead >= stale):
                damped[i] += 1
                continue
            if cell[HOPS] != hops:
                cell[CHANGED] = 1
                dirty[i] = True
            cell[NEXT], cell[HOPS], cell[SEQ] = neighbour, hops, sequence
    changed = np.flatnonzero(dirty)
    damping = np.flatnonzero(damped)
    return changed, damping, damped[damping]
