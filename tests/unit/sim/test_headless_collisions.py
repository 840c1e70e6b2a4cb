"""No collisions in the headless evaluator: the proximity sensor and the safety filter
keep every pair of coverage circles apart while a swarm forms a shape."""

from __future__ import annotations

import pathlib

from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _min_separation(proximity_period_s: float) -> dict:
    """12 robots of the three types crossing into an 8 m square (seed 3, where robots
    meet on the way in)."""
    scenario = Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                        n_beacons=3, half_size=15.0, seed=3, duration_s=60.0,
                        proximity_period_s=proximity_period_s)
    return HeadlessSwarm(scenario).run().metrics


def test_measured_offsets_keep_coverage_circles_apart():
    with_sensor = _min_separation(0.1)
    # min_separation_ratio: smallest distance / (r_i + r_j) over every control step; 1
    # is contact of the coverage circles (the pybullet bodies fit inside them).
    assert with_sensor['min_separation_ratio'] >= 1.0 and with_sensor['contacts'] == 0
    # Avoidance on the neighbours' broadcast estimates alone (no sensor): they overlap.
    without = _min_separation(0.0)
    assert without['min_separation_ratio'] < 1.0 and without['contacts'] >= 1
