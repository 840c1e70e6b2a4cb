"""flood_memory: every router of a store holds exactly the keys a first-in-first-out
memory of its size holds (a key enters when first handled, the oldest leaves), however
the receivers of each flood overlap, while slots are reused and the arrays grow."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from swarm_agent.flood_memory import FloodMemory


class _Fifo:
    """The definition: the last ``size`` keys handled, each entered once."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.keys: OrderedDict[tuple[int, int], None] = OrderedDict()
        self.duplicates = 0

    def hear(self, key: tuple[int, int]) -> bool:
        if key in self.keys:
            self.duplicates += 1
            return False
        self.keys[key] = None
        if len(self.keys) > self.size:
            self.keys.popitem(last=False)
        return True


def test_each_row_holds_what_a_fifo_of_its_size_holds(kernels):
    rng = np.random.default_rng(7)
    sizes = [1, 3, 8, 8, 20, 50]
    memory = FloodMemory()
    rows = [memory.add_row(size) for size in sizes]
    fifos = [_Fifo(size) for size in sizes]
    for step in range(3000):
        # Keys of a few origins, ids near each origin's current one: copies repeat.
        origin = int(rng.integers(0, 4))
        key = (origin, int(step // 4 + rng.integers(0, 30)) & 0xFFFF)
        heard = np.flatnonzero(rng.random(len(rows)) < 0.6)
        rng.shuffle(heard)
        first = memory.first_copies(np.array([rows[i] for i in heard], dtype=np.int64), key)
        assert first.tolist() == [fifos[i].hear(key) for i in heard.tolist()]
        if step % 7 == 0:   # a router's own flood
            i = int(rng.integers(0, len(rows)))
            own = (9, step)
            assert memory.remember(rows[i], own) == fifos[i].hear(own)
    for row, fifo in zip(rows, fifos):
        assert memory.held(row) == list(fifo.keys)
        assert memory.duplicates[row] == fifo.duplicates
    # Slots of keys nobody holds were reused: the slots in use stay near what the rows
    # hold together, not the thousands of keys heard.
    assert len(memory._slot) <= 2 * sum(sizes) and memory.at.shape[0] <= 4 * sum(sizes)


def test_a_row_added_later_holds_nothing_and_rows_grow(kernels):
    memory = FloodMemory()
    a = memory.add_row(4)
    assert memory.first_copies(np.array([a]), (1, 1)).tolist() == [True]
    late = [memory.add_row(4) for _ in range(5)]       # the arrays double under them
    both = np.array([a, *late], dtype=np.int64)
    assert memory.first_copies(both, (1, 1)).tolist() == [False] + [True] * 5
    assert memory.first_copies(both, (1, 1)).tolist() == [False] * 6
    assert [memory.held(r) for r in both.tolist()] == [[(1, 1)]] * 6
