"""One transmission handed to all its receivers at once (``reception.receive``, issue 23)
is the same run as handing it to each receiver on its own, as a node does."""

from __future__ import annotations

import pathlib

import numpy as np

from swarm_agent import reception
from swarm_common.shapes import load_shape
from swarm_sim import headless
from swarm_sim.headless import HeadlessSwarm, Scenario

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _run(monkeypatch, one_by_one: bool):
    if one_by_one:
        def each(t, packet, heard):
            for brain in heard.brains:
                reception.receive(t, packet, (brain,))
        monkeypatch.setattr(headless, 'receive', each)
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=2, duration_s=40.0)
    swarm = HeadlessSwarm(scenario)
    record = swarm.run()
    return record, [(b.router.stats, b.auth_stats, dict(b.stats)) for b in swarm.brains]


def test_receiving_in_one_call_is_receiving_one_by_one(monkeypatch):
    together, stats_together = _run(monkeypatch, one_by_one=False)
    apart, stats_apart = _run(monkeypatch, one_by_one=True)
    for key in ('positions', 'velocities', 'estimates', 'goal_ids', 'digests', 'modes'):
        assert np.array_equal(getattr(together, key), getattr(apart, key)), key
    # Every router counted the same frames: delivered, duplicates, pruned, forwarded...
    assert stats_together == stats_apart
    assert together.metrics['medium'] == apart.metrics['medium']
    assert sum(s[0].get('duplicates', 0) for s in stats_together) > 0
