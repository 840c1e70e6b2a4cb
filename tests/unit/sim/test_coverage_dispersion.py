"""coverage_dispersion (the mean distance to the nearest robot, over its hexagonal least)
and the shape-change metrics built on it."""

import math

import numpy as np
import pytest
from shapely.geometry import box, Point

from swarm_common.shapes import Shape
from swarm_sim.metrics import (
    change_metrics,
    coverage_dispersion,
    HEXAGON_MEAN_DISTANCE,
)


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


def _square_run(arrive: float):
    """Four robots on a 2 x 2 lattice of a 10 m square; at 2 s the square jumps 20 m
    along x and the robots slide after it at 20 m per (arrive - 2) s."""
    shapes = [(0.0, Shape('a', box(0.0, 0.0, 10.0, 10.0), ())),
              (2.0, Shape('b', box(20.0, 0.0, 30.0, 10.0), ()))]
    lattice = np.array([[2.5, 2.5], [7.5, 2.5], [2.5, 7.5], [7.5, 7.5]])
    times = np.arange(0.0, 40.0, 1.0)
    shift = np.clip((times - 2.0) / (arrive - 2.0), 0.0, 1.0) * 20.0
    positions = lattice[None] + np.stack([shift, np.zeros_like(shift)], axis=1)[:, None]
    return times, positions, np.ones((len(times), 4), bool), shapes


def test_a_shape_change_reports_the_lag_and_the_dispersion_while_it_lasts():
    times, positions, alive, shapes = _square_run(arrive=5.0)
    metrics = change_metrics(times, positions, alive, shapes)
    assert metrics['coverage_lags'] == [3.0]          # all inside from 5 s on
    # The window runs from the change (2 s) to 20 s after it, both included: 3 frames on
    # the way (2, 3, 4 s), 18 at rest on the lattice (a square lattice is a little
    # worse than the hexagonal one).
    at_rest = coverage_dispersion(shapes[1][1], positions[-1])
    on_the_way = [coverage_dispersion(shapes[1][1], positions[k]) for k in (2, 3, 4)]
    assert 1.0 < at_rest < 1.1 and min(on_the_way) > at_rest
    assert metrics['dispersion_during_change'] == pytest.approx(
        (sum(on_the_way) + 18 * at_rest) / 21)


def test_a_change_never_completed_has_no_lag_and_no_change_has_no_metrics():
    times, positions, alive, shapes = _square_run(arrive=100.0)
    assert change_metrics(times, positions, alive, shapes)['coverage_lags'] == [None]
    assert change_metrics(times, positions, alive, shapes[:1]) == {}
