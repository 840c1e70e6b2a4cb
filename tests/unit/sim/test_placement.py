"""Robots stand near, not at, their fleet positions (swarm_common.fleet.place_fleet), and
the brains start from the fleet positions with the placement error as their prior."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from shapely.geometry import box

from swarm_common.fleet import FleetError, place_fleet, PLACEMENT_STD_M, RobotSpec
from swarm_common.shapes import load_shape
from swarm_sim.headless import HeadlessSwarm, Scenario

SQUARE = pathlib.Path(__file__).resolve().parents[2] / 'data' / 'square_8m.json'


def _grid(n_side: int, spacing: float) -> list[RobotSpec]:
    return [RobotSpec(k, 1, False, spacing * (k % n_side), spacing * (k // n_side))
            for k in range(n_side * n_side)]


def _errors(configured, placed) -> np.ndarray:
    return np.array([[p.x - c.x, p.y - c.y] for c, p in zip(configured, placed)])


def test_placement_error_has_the_stated_spread_and_is_seeded():
    """400 robots 10 m apart (nothing to avoid): the 800 error components are
    N(0, 0.3^2), so their sample deviation is 0.3 m within 10 % (4 standard errors of
    2.5 %) and their mean is 0 within 4 standard errors (0.3 / sqrt(800) = 1.1 cm)."""
    fleet = _grid(20, 10.0)
    placed = place_fleet(fleet, 0.3, seed=5)
    e = _errors(fleet, placed)
    assert abs(e.std() - 0.3) < 0.03
    assert np.all(np.abs(e.mean(axis=0)) < 4 * 0.3 / np.sqrt(e.size))
    assert [(r.id, r.type, r.is_beacon, r.yaw) for r in placed] == \
        [(r.id, r.type, r.is_beacon, r.yaw) for r in fleet]
    assert place_fleet(fleet, 0.3, seed=5) == placed
    assert not np.allclose(_errors(fleet, place_fleet(fleet, 0.3, seed=6)), e)
    assert place_fleet(fleet, 0.0, seed=5) == fleet
    assert PLACEMENT_STD_M == 0.3


def test_placed_robots_keep_clear_of_each_other_the_obstacles_and_the_edge():
    """Robots of 0.5 m coverage radius configured 1.3 m apart, the first column 0.55 m
    from an obstacle, the last on the workspace edge: a 0.3 m placement error would
    often make circles overlap or cross, so such draws are redrawn; every placed circle
    is clear of the rest."""
    fleet = _grid(6, 1.3)
    radii = [0.5] * len(fleet)
    wall = box(-3.0, -1.0, -0.55, 9.0)
    placed = place_fleet(fleet, 0.3, seed=2, radii=radii, obstacles=[wall], half_size=7.0)
    xy = np.array([[r.x, r.y] for r in placed])
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2) + 10.0 * np.eye(len(xy))
    assert d.min() >= 1.0
    assert np.all(np.abs(xy) <= 7.0 - 0.5)
    assert min(wall.distance(type(wall.centroid)(p)) for p in xy) >= 0.5
    assert not np.allclose(_errors(fleet, placed), 0.0)


def test_a_fleet_with_no_room_for_the_error_is_refused_with_one_line():
    """A robot configured between two walls that both touch its coverage circle: any
    error at all in x puts it into one of them."""
    fleet = [RobotSpec(0, 3, False, 0.0, 0.0), RobotSpec(1, 3, False, 0.0, 3.0)]
    walls = [box(-5.0, -5.0, -0.5, 1.0), box(0.5, -5.0, 5.0, 1.0)]
    with pytest.raises(FleetError, match='robot 0: no placement error of') as exc:
        place_fleet(fleet, 0.3, seed=0, radii=[0.5, 0.5], obstacles=walls)
    assert '\n' not in str(exc.value)
    with pytest.raises(FleetError, match='placement_std_m must be a finite number'):
        place_fleet(fleet, -1.0, seed=0)


def _scenario(**kwargs) -> Scenario:
    """12 robots of the three types entering an 8 m square (as test_headless_collisions)."""
    return Scenario(shape=load_shape(str(SQUARE)), type_counts={1: 5, 2: 4, 3: 3},
                    n_beacons=3, half_size=15.0, seed=1, **kwargs)


def test_brains_start_from_the_fleet_positions_not_where_the_robots_stand():
    swarm = HeadlessSwarm(_scenario())
    configured = np.array([[r.x, r.y] for r in swarm.fleet])
    estimates = np.array([b.localizer.position for b in swarm.brains])
    np.testing.assert_array_equal(estimates, configured)
    error = np.linalg.norm(swarm.dynamics.positions - configured, axis=1)
    assert np.all(error > 0.0) and error.max() < 5 * PLACEMENT_STD_M
    same = place_fleet(swarm.fleet, PLACEMENT_STD_M, 1, radii=list(swarm.radii),
                       half_size=15.0)
    np.testing.assert_array_equal(swarm.dynamics.positions, [[r.x, r.y] for r in same])
    for brain in swarm.brains:
        np.testing.assert_allclose(brain.localizer.covariance[:2, :2],
                                   np.eye(2) * PLACEMENT_STD_M ** 2)


def test_a_placed_swarm_still_settles_and_localizes():
    """The 12-robot scene settles inside its 120 s, and after the first fixes no
    estimate is as far off as a robot's coverage diameter (1 m) at the end."""
    swarm = HeadlessSwarm(_scenario(duration_s=120.0))
    record = swarm.run()
    m = record.metrics
    assert m['settling_time'] is not None and m['settling_time'] < 120.0, m['settling_time']
    assert m['fraction_inside'] == 1.0
    final_error = np.linalg.norm(record.estimates[-1] - record.positions[-1], axis=1)
    assert final_error.max() < 1.0, final_error
