"""DSDV neighbour tables as arrays, one row per router of a process, and the rule every
frame heard applies to them as a kernel.

A router's neighbours are the agents it heard directly (thesis 3.1.2: a heartbeat or a
dump makes its sender a neighbour; ``neighbour_timeout_s`` of silence breaks the link).
For each, the router keeps when it last heard it, and for the link's loss (``link_loss``:
the flood relays' redundancy, ``flood_relay.extra_copies``) when it last heard a
heartbeat and how many heartbeats it heard and the neighbour sent, both decayed by
``loss_memory`` a heartbeat. A ``NeighbourGrid`` holds these for every router of a
process (``AddressGrid``: a row per router, a column per radio address):

    cells[p, c] = (heard at, last heartbeat at, heartbeats heard, heartbeats sent)

NaN times: not a neighbour (not heard since the link last broke) / no heartbeat heard.
``NeighbourTable`` is one router's view. ``heard`` applies one frame to all its receivers
in one call of the kernel ``_heard_from`` (a heartbeat reaches 24 brains on average in
the 50-agent trial; per receiver in Python it was 3 us a delivery, 1.1 million a trial).
"""

from __future__ import annotations

import math

import numpy as np

from swarm_agent.address_grid import AddressGrid
from swarm_common.jit import kernel

HEARD_AT, BEAT_AT, BEATS_HEARD, BEATS_SENT = range(4)   # fields of a cell
_EMPTY = (math.nan, math.nan, 0.0, 0.0)


class NeighbourGrid(AddressGrid):
    """The neighbour tables of a process's routers; see the module docstring."""

    def __init__(self) -> None:
        super().__init__(_EMPTY, np.float64)


class NeighbourTable:
    """One router's neighbours (row ``row`` of ``grid``)."""

    def __init__(self, grid: NeighbourGrid, row: int) -> None:
        self.grid = grid
        self.row = row

    def _cells(self) -> np.ndarray:
        """This table's cells of the columns in use (a view)."""
        return self.grid.cells[self.row, :self.grid.width]

    def heard(self) -> dict[int, float]:
        """Neighbour -> when last heard (a copy), by address."""
        times = self._cells()[:, HEARD_AT]
        cols = np.flatnonzero(~np.isnan(times))
        cols = cols[np.argsort(self.grid.ids[cols])]
        return dict(zip(self.grid.ids[cols].tolist(), times[cols].tolist()))

    def ids(self) -> set[int]:
        """The neighbours heard."""
        times = self._cells()[:, HEARD_AT]
        return set(self.grid.ids[:self.grid.width][~np.isnan(times)].tolist())

    def silent(self, t: float, timeout: float) -> tuple[list[int], float]:
        """The neighbours silent for more than ``timeout`` at ``t``, and the time the
        next of the others falls silent (inf: none left)."""
        times = self._cells()[:, HEARD_AT]
        with np.errstate(invalid='ignore'):
            late = t - times > timeout
        gone = self.grid.ids[:self.grid.width][late].tolist()
        left = times[~np.isnan(times) & ~late]
        return gone, (float(left.min()) + timeout if len(left) else math.inf)

    def forget(self, neighbour: int) -> None:
        """The link to ``neighbour`` broke: no longer a neighbour, its counts dropped."""
        c = self.grid.column[neighbour]
        if c >= 0:
            self.grid.cells[self.row, c] = _EMPTY

    def loss(self) -> float:
        """Share of the neighbours' heartbeats not heard (recent, decayed)."""
        cells = self._cells()
        sent = float(cells[:, BEATS_SENT].sum())
        return 1.0 - float(cells[:, BEATS_HEARD].sum()) / sent if sent > 0.0 else 0.0


def heard(grid: NeighbourGrid, rows: np.ndarray, neighbour: int, t: float, beat: bool,
          period: float, memory: float) -> np.ndarray:
    """``neighbour`` heard directly at ``t`` in the tables ``rows`` of ``grid``: a
    heartbeat (``beat``) or a dump. Returns the positions in ``rows`` of the tables that
    did not have it as a neighbour."""
    col = grid.column_of(neighbour)           # may grow the cells: before reading them
    return _heard_from(grid.cells, rows, col, t, beat, period, memory)


_CELLS = NeighbourGrid().cells
_ROWS = np.zeros(1, dtype=np.int64)


@kernel(_CELLS, _ROWS, 0, 1.0, True, 0.5, 0.95)
def _heard_from(cells: np.ndarray, rows: np.ndarray, col: int, t: float, beat: bool,
                period: float, memory: float) -> np.ndarray:
    """The neighbour of column ``col`` heard at ``t`` in each table of ``rows``; with a
    heartbeat (``beat``), the time since its last one heard tells how many it sent
    (at least one, the period's nearest multiple), and the counts decay by ``memory``
    a heartbeat sent. Returns the positions in ``rows`` of the tables that did not have
    it as a neighbour."""
    new = np.zeros(rows.shape[0], dtype=np.int64)
    n = 0
    for i in range(rows.shape[0]):
        cell = cells[rows[i], col]
        if math.isnan(cell[HEARD_AT]):
            new[n] = i
            n += 1
        cell[HEARD_AT] = t
        if not beat:
            continue
        if math.isnan(cell[BEAT_AT]):
            cell[BEAT_AT], cell[BEATS_HEARD], cell[BEATS_SENT] = t, 1.0, 1.0
            continue
        sent = max(1.0, np.rint((t - cell[BEAT_AT]) / period))
        keep = memory ** sent
        cell[BEAT_AT] = t
        cell[BEATS_HEARD] = cell[BEATS_HEARD] * keep + 1.0
        cell[BEATS_SENT] = cell[BEATS_SENT] * keep + sent
    return new[:n]
