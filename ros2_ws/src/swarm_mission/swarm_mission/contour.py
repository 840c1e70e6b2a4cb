"""Discrete contour utilities of thesis 3.2.1 over equally spaced boundary samples.

The thesis evaluates its contour integrals on samples z_k with equal spacing
||z_{k+1} - z_k|| = dz (eqs. 3.61, 3.64, 3.67, 3.73, 3.94, 3.98). ``sample_boundary``
produces those samples for every ring of a shape; the functions below evaluate the
winding number (eqs. 3.51-3.58), length (eq. 3.63), centre (eq. 3.66) and area (eq.
3.72) on one closed ring of samples, vectorised over samples and query points.

Note (DESIGN.md): eq. 3.66 is the mean of the boundary samples, i.e. the centroid of
the curve, not the area centroid (``Shape.centroid``). Bubble packing starts from the
area centroid, which lies inside convex shapes; the artificial-forces method uses
eq. 3.66 as the thesis does.
"""

from __future__ import annotations

import numpy as np
from shapely.geometry import LinearRing, Polygon


class ContourError(ValueError):
    """Bad contour input (shape of the sample array, spacing)."""


def _as_polygon(shape_or_polygon) -> Polygon:
    region = getattr(shape_or_polygon, 'region', shape_or_polygon)
    if not isinstance(region, Polygon):
        raise ContourError(f'expected a Shape or shapely Polygon, got {type(region).__name__}')
    return region


def sample_ring(coords: np.ndarray, step: float) -> np.ndarray:
    """Equally spaced samples (arc length ``step`` or just under) of one closed ring.

    The closing vertex is not repeated: sample k+1 follows sample k and sample 0
    follows the last one, as eqs. 3.58-3.61 require.
    """
    if not (np.isfinite(step) and step > 0):
        raise ContourError(f'contour step must be a positive length in metres, got {step!r}')
    pts = np.asarray(coords, dtype=float)
    if not np.array_equal(pts[0], pts[-1]):
        pts = np.vstack([pts, pts[:1]])
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(3, int(np.ceil(cum[-1] / step)))
    s = np.linspace(0.0, cum[-1], n, endpoint=False)
    return np.column_stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])


def sample_rings(shape_or_polygon, step: float = 0.01) -> list[np.ndarray]:
    """Samples of each ring (outer first, then holes) as separate (M_j, 2) arrays."""
    region = _as_polygon(shape_or_polygon)
    rings: list[LinearRing] = [region.exterior, *region.interiors]
    return [sample_ring(np.asarray(r.coords), step) for r in rings]


def sample_boundary(shape_or_polygon, step: float = 0.01) -> np.ndarray:
    """(M, 2) equally spaced samples of every ring of the shape (outer and holes), eq. 3.94."""
    return np.vstack(sample_rings(shape_or_polygon, step))


def _check_ring(samples_ring: np.ndarray) -> np.ndarray:
    ring = np.asarray(samples_ring, dtype=float)
    if ring.ndim != 2 or ring.shape[1] != 2 or len(ring) < 3:
        raise ContourError(f'a contour must be an (M >= 3, 2) array of samples, got shape '
                           f'{ring.shape}')
    if not np.isfinite(ring).all():
        raise ContourError('contour samples contain NaN or infinite values')
    return ring


def winding_number(samples_ring: np.ndarray, points: np.ndarray,
                   chunk: int = 4_000_000) -> np.ndarray:
    """Cauchy winding number n(C, z_i) of one closed sampled ring around ``points`` (eq. 3.51).

    Discrete form of eq. 3.58: the contour integral of dz / (z - z_i) over the sampled
    polygon is summed exactly, segment by segment, as the angle arg((z_{k+1} - z_i) /
    (z_k - z_i)) swept by each segment (the first-order A_k, B_k terms of eqs. 3.59-3.60
    converge to the same value as dz -> 0). Returns integers per point (+1 inside a
    counter-clockwise ring, -1 inside a clockwise one, 0 outside); points on the ring
    itself give an undefined but finite value.
    """
    ring = _check_ring(samples_ring)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    z = ring[:, 0] + 1j * ring[:, 1]
    out = np.empty(len(pts))
    rows = max(1, chunk // len(z))
    for start in range(0, len(pts), rows):
        zi = (pts[start:start + rows, 0] + 1j * pts[start:start + rows, 1])[:, None]
        d = z[None, :] - zi
        out[start:start + rows] = np.angle(np.roll(d, -1, axis=1) / d).sum(axis=1)
    return np.rint(out / (2 * np.pi)).astype(int)


def contour_length(samples_ring: np.ndarray) -> float:
    """Length of the closed sampled ring, eq. 3.63."""
    ring = _check_ring(samples_ring)
    return float(np.hypot(*(np.roll(ring, -1, axis=0) - ring).T).sum())


def contour_center(samples_ring: np.ndarray) -> np.ndarray:
    """Centre of the formation shape as the mean of equally spaced samples, eq. 3.66."""
    return _check_ring(samples_ring).mean(axis=0)


def contour_area(samples_ring: np.ndarray) -> float:
    """Signed area enclosed by the sampled ring by Green's theorem, eq. 3.72 (CCW > 0)."""
    ring = _check_ring(samples_ring)
    d = np.roll(ring, -1, axis=0) - ring
    return float(0.5 * (ring[:, 0] * d[:, 1] - ring[:, 1] * d[:, 0]).sum())
