"""Mesh quality of a partition or of final agent positions (thesis 3.2.3, 4.3.1, 4.3.5).

Both irregularities are computed on the Delaunay triangulation of the node positions
(scipy.spatial.Delaunay), the dual of the thesis's Voronoi diagram (Fig. 3.28).

Two definitions, selected by ``count_boundary``:

- ``count_boundary=False`` (ours, default): keep the Delaunay triangles whose centroid
  lies inside the shape region. A node is interior when it belongs to a kept triangle
  and to no edge of the kept mesh's border (an edge used by exactly one kept triangle).
  epsilon_t (eq. 3.104, D = 6) averages |degree - 6| over the interior nodes, the degree
  counted along kept edges; epsilon_g (eq. 3.106, A = 0.5) averages 0.5 - r/R over the
  kept triangles (r, R: in- and circumradius). A perfect hexagonal lattice scores 0, 0.
- ``count_boundary=True`` (what the thesis's figures (epsilon_t 2.1-3.95) must come from): every
  triangle of the Delaunay triangulation of the convex hull and every node, boundary
  and hull nodes included, with their full Delaunay degree.

Eq. 3.106 speaks of Voronoi cells, but A = 0.5 is the in/circumradius ratio of the
equilateral triangle, so epsilon_g is evaluated over Delaunay triangles (DESIGN.md).
Fewer than three nodes, collinear nodes or no interior node give NaN.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError
import shapely
from shapely.geometry import Polygon

D_TRIANGLES = 6      # eq. 3.105, 2-D
A_TRIANGLES = 0.5    # eq. 3.107, 2-D


class MeshQualityError(ValueError):
    """Node positions that cannot be measured (wrong array shape, NaN)."""


def _points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise MeshQualityError(f'points must be an (n, 2) array, got shape {pts.shape}')
    if not np.isfinite(pts).all():
        raise MeshQualityError('points contain NaN or infinite coordinates; drop them first')
    return pts


def mesh_triangles(points, shape, *, count_boundary: bool = False) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """Triangles measured and the interior-node mask: ((m, 3) indices, (n,) bool)."""
    pts = _points(points)
    n = len(pts)
    empty = (np.zeros((0, 3), dtype=int), np.zeros(n, dtype=bool))
    if n < 3:
        return empty
    try:
        tri = Delaunay(pts).simplices
    except QhullError:
        return empty
    if count_boundary:
        return tri, np.ones(n, dtype=bool)
    region: Polygon = getattr(shape, 'region', shape)
    centroids = pts[tri].mean(axis=1)
    kept = tri[shapely.contains_xy(region, centroids[:, 0], centroids[:, 1])]
    edges = np.sort(kept[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    interior = np.zeros(n, dtype=bool)
    interior[kept.ravel()] = True
    interior[unique[counts == 1].ravel()] = False
    return kept, interior


def _degrees(triangles: np.ndarray, n: int) -> np.ndarray:
    edges = np.unique(np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    return np.bincount(edges.ravel(), minlength=n)


def epsilon_t(points, shape, *, count_boundary: bool = False) -> float:
    """Topological mesh irregularity, eq. 3.104: mean |gamma_i - D| over interior nodes, D=6."""
    pts = _points(points)
    triangles, interior = mesh_triangles(pts, shape, count_boundary=count_boundary)
    if len(triangles) == 0 or not interior.any():
        return float('nan')
    degree = _degrees(triangles, len(pts))
    return float(np.abs(degree[interior] - D_TRIANGLES).mean())


def radius_ratios(points, triangles: np.ndarray) -> np.ndarray:
    """In/circumradius ratio r/R of each triangle (0 for degenerate ones)."""
    p = np.asarray(points, dtype=float)[triangles]
    a = np.linalg.norm(p[:, 1] - p[:, 2], axis=1)
    b = np.linalg.norm(p[:, 2] - p[:, 0], axis=1)
    c = np.linalg.norm(p[:, 0] - p[:, 1], axis=1)
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = (2 * area / (a + b + c)) / (a * b * c / (4 * area))
    return np.where(area > 0, ratio, 0.0)


def epsilon_g(points, shape, *, count_boundary: bool = False) -> float:
    """Geometric mesh irregularity, eq. 3.106: mean (A - r_i / R_i) over triangles, A=0.5."""
    pts = _points(points)
    triangles, _ = mesh_triangles(pts, shape, count_boundary=count_boundary)
    if len(triangles) == 0:
        return float('nan')
    return float((A_TRIANGLES - radius_ratios(pts, triangles)).mean())


def irregularities(points, shape) -> dict[str, float]:
    """Both irregularities under both definitions, keyed as in the metrics files."""
    return {'epsilon_t': epsilon_t(points, shape), 'epsilon_g': epsilon_g(points, shape),
            'epsilon_t_with_boundary': epsilon_t(points, shape, count_boundary=True),
            'epsilon_g_with_boundary': epsilon_g(points, shape, count_boundary=True)}
