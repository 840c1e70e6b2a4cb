"""Per-receiver state of a process's brains by radio address: one array, one call a frame.

Rows are the receivers of a process (a brain's router or replay window: the headless
evaluator's swarm, a composed container's agents; one row for a node alone), columns the
16-bit radio addresses heard of so far (``column[address]``, -1: none yet; ``ids[c]`` the
address of column c), and ``cells[row, column]`` a fixed record of ``len(empty)``
fields. A kernel then updates every receiver of one frame in one call over ``rows``
(``route_table``, ``frame_auth``). Both dimensions grow by doubling, so ``cells`` is a
new array after ``add_row``, ``column_of`` and ``columns``: read it after them.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np

ADDRESSES = 1 << 16


class AddressGrid:
    """Receivers by radio addresses, each cell a record initialised to ``empty``."""

    def __init__(self, empty: Sequence[float], dtype: type) -> None:
        self._empty = np.array(empty, dtype=dtype)
        self.column = np.full(ADDRESSES, -1, dtype=np.int64)
        self.ids = np.zeros(8, dtype=np.int64)      # column -> address
        self.width = 0                              # columns in use
        self.cells = self._new(1, 8)
        self.height = 0                             # rows in use
        self._groups: dict[Hashable, object] = {}

    def group(self, settings: Hashable) -> object:
        """A token for this grid's receivers with these ``settings`` (those a kernel takes
        as scalars): the receivers of a frame that hold one token are updated in one
        call, which an identity check per receiver tells (``open_all``, ``hear``)."""
        return self._groups.setdefault(settings, object())

    def add_row(self) -> int:
        """A new receiver, every cell empty; returns its row."""
        if self.height == len(self.cells):
            self._grow(2 * self.height, self.cells.shape[1])
        self.height += 1
        return self.height - 1

    def column_of(self, address: int) -> int:
        """The column of ``address`` (0..65535), added if new."""
        c = int(self.column[address])
        if c >= 0:
            return c
        if self.width == len(self.ids):
            self.ids = np.concatenate([self.ids, np.zeros_like(self.ids)])
            self._grow(len(self.cells), 2 * self.width)
        c = self.width
        self.column[address], self.ids[c] = c, address
        self.width += 1
        return c

    def columns(self, addresses: np.ndarray) -> np.ndarray:
        """The columns of ``addresses``, new ones added."""
        cols = self.column[addresses]
        if (cols < 0).any():
            for address in addresses[cols < 0].tolist():
                self.column_of(address)
            cols = self.column[addresses]
        return cols

    def _new(self, height: int, width: int) -> np.ndarray:
        return np.tile(self._empty, (height, width, 1))

    def _grow(self, height: int, width: int) -> None:
        grown = self._new(height, width)
        grown[:self.cells.shape[0], :self.cells.shape[1]] = self.cells
        self.cells = grown
