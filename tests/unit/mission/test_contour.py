"""Discrete contour utilities of thesis 3.2.1 cross-checked against shapely."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
import shapely

from swarm_common.shapes import load_shape
from swarm_mission.contour import (
    contour_area,
    contour_center,
    contour_length,
    ContourError,
    sample_boundary,
    sample_rings,
    winding_number,
)


@pytest.mark.parametrize('name', ['thesis_shape_1', 'thesis_shape_3', 'table43_4'])
def test_length_area_against_shapely(name):
    shape = load_shape(name)
    rings = sample_rings(shape, 0.01)
    lengths = [contour_length(r) for r in rings]
    assert sum(lengths) == pytest.approx(shape.boundary_length, rel=1e-4)
    areas = [contour_area(r) for r in rings]       # holes are clockwise: negative
    assert sum(areas) == pytest.approx(shape.area, rel=1e-4)


def test_samples_are_equally_spaced_at_the_step():
    ring = sample_rings(load_shape('thesis_shape_2'), 0.05)[0]
    gaps = np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1)
    assert gaps.max() <= 0.05 + 1e-9
    assert np.median(gaps) == pytest.approx(0.05, rel=0.01)
    assert len(sample_boundary(load_shape('thesis_shape_3'), 0.01)) > 8000


def test_center_is_the_sample_mean_not_the_area_centroid():
    ring = sample_rings(load_shape('circle_314'), 0.01)[0]
    assert np.allclose(contour_center(ring), 0.0, atol=1e-3)
    boomerang = load_shape('thesis_shape_2')
    c = contour_center(sample_rings(boomerang, 0.01)[0])
    lin = np.asarray(boomerang.region.exterior.centroid.coords)[0]   # curve centroid
    assert np.allclose(c, lin, atol=0.01)
    assert np.linalg.norm(c - boomerang.centroid) > 0.1


@settings(max_examples=25, deadline=None)
@given(st.integers(min_value=0, max_value=10_000))
def test_winding_number_matches_shapely_contains(seed):
    shape = load_shape('thesis_shape_3')
    rng = np.random.default_rng(seed)
    minx, miny, maxx, maxy = shape.region.bounds
    pts = rng.uniform([minx - 2, miny - 2], [maxx + 2, maxy + 2], size=(200, 2))
    keep = shapely.distance(shape.region.boundary, shapely.points(pts)) > 0.05
    pts = pts[keep]
    total = sum(winding_number(r, pts) for r in sample_rings(shape, 0.05))
    assert np.array_equal(total == 1, shapely.contains_xy(shape.region, pts[:, 0], pts[:, 1]))
    assert set(np.unique(total)) <= {0, 1}


def test_bad_contour_input():
    with pytest.raises(ContourError, match='positive'):
        sample_boundary(load_shape('circle_314'), 0.0)
    with pytest.raises(ContourError, match='shape'):
        contour_length(np.zeros((2, 2)))
    with pytest.raises(ContourError, match='NaN'):
        contour_area(np.array([[0, 0], [1, np.nan], [1, 1]]))
