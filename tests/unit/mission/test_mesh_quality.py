"""Mesh irregularities (eqs. 3.104, 3.106) on lattices with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import MultiPoint

from swarm_mission.mesh_quality import epsilon_g, epsilon_t, MeshQualityError, radius_ratios


def hex_patch(rings: int, spacing: float = 1.0) -> np.ndarray:
    """Triangular-lattice nodes within ``rings`` hexagonal rings of the origin."""
    pts = []
    for i in range(-rings, rings + 1):
        for j in range(-rings, rings + 1):
            if abs(i + j) <= rings:
                pts.append((i + 0.5 * j, np.sqrt(3) / 2 * j))
    return spacing * np.array(pts)


def test_perfect_hexagonal_patch_scores_zero():
    pts = hex_patch(4, 2.5)
    shape = MultiPoint(pts).convex_hull.buffer(0.5)
    assert epsilon_t(pts, shape) == 0.0
    assert epsilon_g(pts, shape) == pytest.approx(0.0, abs=1e-9)
    # counting boundary nodes (degree 3 or 4 on the hull) is no longer zero
    assert epsilon_t(pts, shape, count_boundary=True) > 0.5


def test_equilateral_and_right_triangle_ratios():
    eq = np.array([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]])
    right = np.array([[0, 0], [1, 0], [0, 1]])
    assert radius_ratios(eq, np.array([[0, 1, 2]]))[0] == pytest.approx(0.5)
    # right isosceles: r = (2 - sqrt 2)/2, R = sqrt(2)/2
    assert radius_ratios(right, np.array([[0, 1, 2]]))[0] == pytest.approx(np.sqrt(2) - 1)


def test_jittered_lattice_is_more_irregular_than_perfect():
    rng = np.random.default_rng(3)
    pts = hex_patch(5)
    shape = MultiPoint(pts).convex_hull.buffer(0.4)
    noisy = pts + rng.normal(scale=0.2, size=pts.shape)
    assert epsilon_t(noisy, shape) > 0.3
    assert epsilon_g(noisy, shape) > 0.03


def test_triangles_outside_a_concave_shape_are_not_counted():
    # Two hexagonal patches joined only through their convex hull: the hull slivers
    # between them lie outside the shape and do not count.
    a, b = hex_patch(2), hex_patch(2) + [12.0, 0.0]
    pts = np.vstack([a, b])
    shape = MultiPoint(a).convex_hull.buffer(0.4).union(MultiPoint(b).convex_hull.buffer(0.4))
    assert epsilon_t(pts, shape) == 0.0
    assert epsilon_g(pts, shape) == pytest.approx(0.0, abs=1e-9)
    assert epsilon_g(pts, shape, count_boundary=True) > 0.05


def test_degenerate_and_bad_input():
    shape = MultiPoint([(0, 0), (1, 0), (0, 1)]).convex_hull.buffer(1)
    assert np.isnan(epsilon_t(np.zeros((2, 2)), shape))
    assert np.isnan(epsilon_t(np.array([[0, 0], [1, 0], [2, 0]]), shape))   # collinear
    with pytest.raises(MeshQualityError, match='NaN'):
        epsilon_g(np.array([[0, 0], [1, np.nan], [0, 1]]), shape)
    with pytest.raises(MeshQualityError, match=r'\(n, 2\)'):
        epsilon_t(np.zeros((3, 3)), shape)
