"""A long shape held by 16 robots with 4 beacons (swarm_mission.beacon_goals in a trial).

The 20 m x 38 m concave chevron spans more than the 22.5 m that 0.9 of the 25 m radio
reaches (thesis 4.1): beacons parked on arbitrary goals leave some goal without three
beacons in reach, whose robot falls LOST and returns home over and over (3.1.3). With
beacon goals every robot can localize where it parks, so the swarm settles.
"""

from __future__ import annotations

import numpy as np
from shapely import affinity
from shapely.geometry import Polygon

from swarm_agent.localization import Mode
from swarm_common.shapes import Shape
from swarm_sim.headless import HeadlessSwarm, Scenario

CHEVRON = Shape('chevron', affinity.translate(
    Polygon([(0, 0), (10, 8), (20, 0), (20, 30), (10, 38), (0, 30), (6, 19)]), -10, -19))


def test_sixteen_robots_four_beacons_settle_on_the_long_shape():
    # Seed 0: beacons of types 1, 2, 3, 3 deployed far apart in a 40 m square around the
    # shape. Measured: settled at 84 s and held 30 s, worst localization error 0.87 m.
    # With the beacons unknown to the mission (no beacon goals) the same trial does not
    # settle in 400 s (37 re-departures).
    swarm = HeadlessSwarm(Scenario(shape=CHEVRON, type_counts={1: 6, 2: 6, 3: 4},
                                   n_beacons=4, seed=0, duration_s=400.0, half_size=20.0))
    record = swarm.run()
    metrics = record.metrics
    assert metrics['outcome'] == 'settled'
    assert metrics['settling_time'] < 400.0
    goals = {g.id: g for g in record.goals}
    assert sum(g.beacon for g in goals.values()) == 4
    final = record.goal_ids[-1]
    for i, goal_id in enumerate(final):
        assert goal_id in goals
        assert goals[goal_id].beacon == bool(record.beacons[i])
    assert len(set(final.tolist())) == len(final)
    assert np.all(record.modes[-1] == int(Mode.NORMAL))
    assert metrics['max_localization_error'] < 1.5
