"""coverage_dispersion: the mean distance to the nearest robot, over its hexagonal least."""

import math

import numpy as np
import pytest
from shapely.geometry import box, Point

from swarm_mission.shapes import Shape
from swarm_sim.metrics import coverage_dispersion, HEXAGON_MEAN_DISTANCE


def _metres(shape: Shape, points) -> float:
    """The mean distance itself, undoing the normalisation."""
    n = len(points)
    return coverage_dispersion(shape, points) * HEXAGON_MEAN_DISTANCE * math.sqrt(
        shape.area / n)


def test_one_robot_at_the_centre_of_a_disc_is_two_thirds_of_the_radius_away():
    disc = Shape('disc', Point(0.0, 0.0).buffer(5.0, 256), ())
    assert _metres(disc, [[0.0, 0.0]]) == pytest.approx(10.0 / 3.0, rel=0.01)


def test_one_robot_at_the_centre_of_a_square():
    # Mean distance from a unit square's points to its centre: (sqrt 2 + asinh 1) / 6.
    square = Shape('square', box(0.0, 0.0, 10.0, 10.0), ())
    exact = 10.0 * (math.sqrt(2.0) + math.asinh(1.0)) / 6.0
    assert _metres(square, [[5.0, 5.0]]) == pytest.approx(exact, rel=0.01)


def test_a_hexagonal_lattice_is_an_even_spread_and_a_bunch_is_not():
    side = 1.0
    rows = [[i * side + (j % 2) * side / 2, j * side * math.sqrt(3.0) / 2]
            for j in range(-30, 31) for i in range(-30, 31)]
    lattice = np.array(rows)
    region = Shape('square', box(-10.0, -10.0, 10.0, 10.0), ())
    inside = lattice[(np.abs(lattice) < 10.0).all(axis=1)]
    assert coverage_dispersion(region, inside) == pytest.approx(1.0, abs=0.03)
    assert coverage_dispersion(region, np.zeros_like(inside)) > 15.0
    # Robots left on one side of the region (a shape that moved away) are worse too.
    assert coverage_dispersion(region, inside * 0.5 - [5.0, 0.0]) > 1.5


def test_no_robots_is_infinitely_dispersed():
    assert coverage_dispersion(Shape('s', box(0, 0, 1, 1), ()), np.zeros((0, 2))) == math.inf
