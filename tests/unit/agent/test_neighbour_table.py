"""Neighbour tables as arrays (swarm_agent.neighbour_table): heard times and the heartbeat
counts behind a router's link loss, for many receivers in one call, compiled and as source.

The expected counts follow from the rule by hand: each heartbeat heard adds one heard
and the heartbeats the neighbour sent since the last one heard (the time between them
over the period, to the nearest whole, at least one), after both decayed by
``memory ** sent``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_agent import neighbour_table
from swarm_agent.dsdv import DsdvConfig, DsdvRouter
from swarm_agent.dsdv_receive import hear
from swarm_agent.neighbour_table import NeighbourGrid, NeighbourTable
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.route_table import RouteStore
from swarm_agent.wire import encode_heartbeat

pytestmark = pytest.mark.usefixtures('kernels')
PERIOD, MEMORY = 0.5, 0.95


def _tables(n: int) -> list[NeighbourTable]:
    grid = NeighbourGrid()
    return [NeighbourTable(grid, grid.add_row()) for _ in range(n)]


def _heard(tables: list[NeighbourTable], neighbour: int, t: float, beat: bool) -> np.ndarray:
    rows = np.array([table.row for table in tables], dtype=np.int64)
    return neighbour_table.heard(tables[0].grid, rows, neighbour, t, beat, PERIOD, MEMORY)


def test_a_missed_heartbeat_counts_as_sent_and_not_heard():
    (table,) = _tables(1)
    for t in (0.0, 0.5, 1.5):   # the heartbeat of 1.0 s was lost
        _heard([table], 7, t, True)
    heard = (1.0 * MEMORY + 1.0) * MEMORY ** 2 + 1.0
    sent = (1.0 * MEMORY + 1.0) * MEMORY ** 2 + 2.0
    assert table.loss() == pytest.approx(1.0 - heard / sent, rel=1e-12)
    assert table.heard() == {7: 1.5}


def test_many_receivers_in_one_call_equal_one_at_a_time():
    """Receivers that heard different histories, updated together and one by one."""
    together, alone = _tables(5), _tables(5)
    rng = np.random.default_rng(3)
    for step in range(60):
        t = 0.5 * step + float(rng.uniform(-0.05, 0.05))
        neighbour = int(rng.integers(1, 4))
        beat = bool(rng.random() < 0.7)
        hearing = [i for i in range(5) if rng.random() < 0.6]
        if not hearing:
            continue
        new = _heard([together[i] for i in hearing], neighbour, t, beat)
        one = [k for k, i in enumerate(hearing) if len(_heard([alone[i]], neighbour, t, beat))]
        assert new.tolist() == one
    for a, b in zip(together, alone):
        assert a.heard() == b.heard() and a.loss() == b.loss()


def test_new_neighbours_silence_and_forgetting():
    a, b = _tables(2)
    assert _heard([a, b], 9, 1.0, False).tolist() == [0, 1]   # both new
    assert _heard([a], 9, 1.2, True).tolist() == []
    _heard([a], 4, 2.0, True)
    assert a.ids() == {4, 9} and b.ids() == {9}
    gone, next_silence = a.silent(3.3, 2.0)   # 9 last heard at 1.2: silent for 2.1 s
    assert gone == [9] and next_silence == 4.0
    a.forget(9)
    assert a.ids() == {4} and a.heard() == {4: 2.0}
    assert a.silent(3.3, 2.0) == ([], 4.0)
    a.forget(4)
    assert a.silent(10.0, 2.0) == ([], math.inf) and a.loss() == 0.0
    # A forgotten neighbour heard again starts its counts afresh.
    assert _heard([a], 9, 11.0, True).tolist() == [0]
    assert a.loss() == 0.0


def test_routers_sharing_a_store_count_the_loss_each_heard():
    """Two routers of one store: one hears every heartbeat, the other every second one;
    the link loss is each router's own (half of recent heartbeats missed tends to 0.5)."""
    store = RouteStore()
    config = DsdvConfig()
    every, half = DsdvRouter(1, config, store=store), DsdvRouter(2, config, store=store)
    sender = 5
    for k in range(200):
        frame = Packet(sender, BROADCAST, int(Kind.HEARTBEAT), k, 1,
                       encode_heartbeat(2 * k, b''))
        hear(k * config.heartbeat_period_s, frame, (every, half) if k % 2 else (every,))
    assert every.link_loss() == 0.0
    assert half.link_loss() == pytest.approx(0.5, abs=0.03)
    assert every.neighbours() == half.neighbours() == {sender}
