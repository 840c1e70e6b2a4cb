"""The flood keys each router remembers, to handle a flood once (thesis 3.1.2, floods).

A router drops a flood copy whose key (origin, flood id) it has handled, and remembers
the last ``memory`` keys it handled (``DsdvConfig.dedup_memory``): a key enters once,
when first handled, and the oldest leaves when there are more, as in a
first-in-first-out set. Held for every router of a process as arrays (issue 23: the
receivers of one flood transmission are checked and updated in one kernel call, not one
set lookup each; a router alone in its process has a memory of one row):

- ``slot[key]``: a row of ``at`` for each key some router may still hold;
- ``at[s, r]``: how many keys router ``r`` had remembered before it remembered the key
  of slot ``s`` (-1: never);
- ``count[r]``: how many keys ``r`` has remembered.

So ``r`` holds the key of slot ``s`` when ``count[r] - memory[r] <= at[s, r]``: the key
is among its last ``memory`` ones, exactly the set a first-in-first-out memory of that
size holds. A slot none holds any more is reused for a new key; ``at`` grows by doubling
when too few are free.
"""

from __future__ import annotations

import numpy as np

from swarm_common.jit import kernel

Key = tuple[int, int]


@kernel(np.full((1, 1), -1, dtype=np.int64), np.zeros(1, dtype=np.int64),
        np.ones(1, dtype=np.int64), np.zeros(1, dtype=np.int64), 0,
        np.zeros(1, dtype=np.int64))
def _first_copies(at: np.ndarray, count: np.ndarray, memory: np.ndarray,
                  duplicates: np.ndarray, slot: int, rows: np.ndarray) -> np.ndarray:
    """For each receiver of ``rows``: whether the key of ``slot`` is new to it (it then
    remembers it) or a copy it holds (counted in ``duplicates``)."""
    first = np.zeros(rows.shape[0], dtype=np.bool_)
    for i in range(rows.shape[0]):
        r = rows[i]
        held = at[slot, r]
        if held >= 0 and held >= count[r] - memory[r]:
            duplicates[r] += 1
        else:
            first[i] = True
            at[slot, r] = count[r]
            count[r] += 1
    return first


class FloodMemory:
    """The remembered flood keys of a process's routers, row for row (module docstring)."""

    def __init__(self) -> None:
        self.at = np.full((64, 1), -1, dtype=np.int64)
        self.count = np.zeros(1, dtype=np.int64)
        self.memory = np.zeros(1, dtype=np.int64)
        self.duplicates = np.zeros(1, dtype=np.int64)   # copies dropped, per row
        self.height = 0
        self._slot: dict[Key, int] = {}
        self._keys: list[Key | None] = []    # slot -> its key (None: free)
        self._free: list[int] = []

    def add_row(self, memory: int) -> int:
        """A new router remembering ``memory`` keys, none yet; returns its row."""
        row = self.height
        if row == self.at.shape[1]:
            self.at = np.concatenate([self.at, np.full_like(self.at, -1)], axis=1)
            for name in ('count', 'memory', 'duplicates'):
                old = getattr(self, name)
                setattr(self, name, np.concatenate([old, np.zeros_like(old)]))
        self.memory[row] = memory
        self.height += 1
        return row

    def first_copies(self, rows: np.ndarray, key: Key) -> np.ndarray:
        """Which receivers of ``rows`` handle the flood ``key`` first (bool per row);
        they remember it, the others count a duplicate."""
        slot = self._slot.get(key)
        if slot is None:
            slot = self._slot[key] = self._new_slot()
            self._keys[slot] = key
        return _first_copies(self.at, self.count, self.memory, self.duplicates, slot, rows)

    def remember(self, row: int, key: Key) -> bool:
        """Router ``row`` remembers ``key`` (its own flood); False if it held it."""
        return bool(self.first_copies(np.array([row], dtype=np.int64), key)[0])

    def held(self, row: int) -> list[Key]:
        """The keys router ``row`` holds, oldest first."""
        n = len(self._keys)
        at = self.at[:n, row]
        slots = np.flatnonzero((at >= 0) & (at >= self.count[row] - self.memory[row]))
        return [self._keys[s] for s in slots[np.argsort(at[slots])].tolist()]

    def _new_slot(self) -> int:
        if not self._free:
            self._collect()
        return self._free.pop()

    def _collect(self) -> None:
        """Free the slots whose key no router holds; double ``at`` when that frees fewer
        than half of them (so each slot is collected at most once per use, amortised)."""
        n, h = len(self._keys), self.height
        at = self.at[:n, :h]
        gone = ~((at >= 0) & (at >= (self.count[:h] - self.memory[:h]))).any(axis=1)
        for s in np.flatnonzero(gone).tolist():
            key = self._keys[s]
            if key is not None:
                del self._slot[key]
                self._keys[s] = None
            self.at[s] = -1
            self._free.append(s)
        if len(self._free) < n // 2 or n == 0:
            size = max(self.at.shape[0], 2 * n)
            if size > self.at.shape[0]:
                self.at = np.concatenate([self.at, np.full((size - self.at.shape[0],
                                                             self.at.shape[1]), -1,
                                                            dtype=np.int64)])
            self._free.extend(range(size - 1, n - 1, -1))
            self._keys.extend([None] * (size - n))
