"""The proximity sensor model (swarm_sim.sensors.ProximityModel): who sees whom, and how
well. Every pair of living robots within range is seen from both ends, as the true
offset (neighbour minus observer) plus noise of ``noise_std`` per axis; nobody beyond
range, and no dead robot, ever appears.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarm_sim.sensors import ProximityModel


def _brute_force(positions, alive, range_m) -> set[tuple[int, int]]:
    """(observer, seen) index pairs of living robots within ``range_m``."""
    living = np.flatnonzero(alive)
    return {(int(i), int(j)) for i in living for j in living
            if i != j and np.hypot(*(positions[j] - positions[i])) <= range_m}


def test_pairs_in_range_are_seen_from_both_ends_at_their_true_offsets():
    rng = np.random.default_rng(5)
    positions = rng.uniform(-10.0, 10.0, (80, 2))
    radii = rng.choice([0.3, 0.45, 0.6], 80)
    alive = rng.random(80) > 0.2
    model = ProximityModel(np.random.default_rng(6), range_m=3.0, noise_std=0.02)
    scan = model.measure(positions, radii, alive)
    seen, errors = set(), []
    for i in range(len(positions)):
        offsets, got_radii = scan.of(i)
        assert offsets.shape == (len(got_radii), 2)
        for offset, radius in zip(offsets, got_radii):
            # Which robot: the one whose true offset is nearest (robots are metres apart,
            # the noise centimetres).
            j = int(np.argmin(np.hypot(*(positions - positions[i] - offset).T)))
            seen.add((i, j))
            errors.append(offset - (positions[j] - positions[i]))
            assert radius == radii[j]
    expected = _brute_force(positions, alive, 3.0)
    assert len(expected) > 50                      # a test of something
    assert seen == expected                        # both ends, nobody beyond range, no dead
    assert len(scan.observers) == len(expected)    # each pair once per end, no duplicates
    errors = np.array(errors)
    assert np.abs(errors).max() < 5 * 0.02
    assert errors.std() == pytest.approx(0.02, rel=0.25)


def test_dead_robots_neither_see_nor_are_seen_and_a_lone_robot_sees_nobody():
    positions = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.5], [10.0, 10.0], [1.0, 1.0]])
    radii = np.array([0.3, 0.45, 0.6, 0.3, 0.45])
    alive = np.array([True, True, True, True, False])
    model = ProximityModel(np.random.default_rng(0), range_m=3.0, noise_std=0.0)
    scan = model.measure(positions, radii, alive)
    offsets, got = scan.of(0)
    assert sorted(map(tuple, offsets.tolist())) == [(0.0, 2.5), (2.0, 0.0)]
    assert sorted(got.tolist()) == [0.45, 0.6]
    offsets, got = scan.of(1)                      # 1-2 are 3.2 m apart: out of range
    assert offsets.tolist() == [[-2.0, 0.0]] and got.tolist() == [0.3]
    for lonely in (3, 4):                          # far from everyone; dead
        offsets, got = scan.of(lonely)
        assert offsets.shape == (0, 2) and got.shape == (0,)
    # Everyone alive by default: robot 4 (1.4 m from 0 and 1, 1.8 from 2) is seen.
    scan = model.measure(positions, radii)
    assert len(scan.of(4)[0]) == 3 and len(scan.of(0)[0]) == 3
    # One robot alone in the world, or nobody alive: empty scans, not errors.
    scan = model.measure(positions[:1], radii[:1])
    assert scan.of(0)[0].shape == (0, 2)
    scan = model.measure(positions, radii, np.zeros(5, dtype=bool))
    assert all(len(scan.of(i)[1]) == 0 for i in range(5))


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match='range_m must be positive'):
        ProximityModel(np.random.default_rng(0), range_m=0.0)
    with pytest.raises(ValueError, match='noise_std not negative'):
        ProximityModel(np.random.default_rng(0), noise_std=-0.1)
