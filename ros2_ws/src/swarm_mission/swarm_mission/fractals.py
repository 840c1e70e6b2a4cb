"""Randomized fractals partition (thesis 3.2.2.1, Algorithm 2, eqs. 3.99-3.101).

Algorithm 2 (RANDOMIZED_FRACTALS_ALGORITHM): coverage circles are taken largest first
(Shier and Bourke fill with decreasing areas) and each is put uniformly at random in
its free configuration space; when the free space is full the algorithm stops and
tells the operator how much larger the shape must be.

The Hurwitz-zeta area schedule (eq. 3.99, A_i = A / (zeta(c, N) (i + N)^c), whose sum
over all i is A, eq. 3.101) sets the area each placed circle claims: circle i keeps
other circles out of a disk of area max(A_i, pi r_i^2). N is solved so that the n
claims together cover ``fill`` of the shape (scipy.special.zeta, scipy.optimize.brentq),
which spreads the agents over the whole shape; when a claim no longer fits, the circle
falls back to claiming only its own coverage circle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.special import zeta
import shapely
from shapely.geometry import Polygon

from swarm_common.goals import check_fits, PartitionError


@dataclass
class FractalConfig:
    """Randomized fractals parameters (YAML: config/partition.yaml)."""

    c: float = 1.3            # eq. 3.99 exponent, c > 1
    fill: float = 0.5         # fraction of the area claimed by the n circles together
    batch: int = 256          # random candidates drawn per try
    tries: int = 8            # batches before the exact free space is computed

    def __post_init__(self) -> None:
        if not (self.c > 1 and 0 < self.fill < 1 and self.batch > 0 and self.tries > 0):
            raise PartitionError(f'bad fractal parameters {self}: need c > 1, 0 < fill < 1, '
                                 'batch and tries positive')


def zeta_areas(area: float, n: int, c: float, big_n: float) -> np.ndarray:
    """Eq. 3.99: A_i = A / (zeta(c, N) (i + N)^c) for i = 0 .. n-1."""
    i = np.arange(n, dtype=float)
    return area / (zeta(c, big_n) * (i + big_n) ** c)


def schedule_offset(n: int, c: float, fill: float) -> float:
    """N such that the first n areas of eq. 3.99 sum to ``fill`` of the total (eq. 3.101).

    sum_{i<n} A_i / A = 1 - zeta(c, N + n) / zeta(c, N), increasing in n, decreasing in N.
    """
    def covered(big_n: float) -> float:
        return 1.0 - zeta(c, big_n + n) / zeta(c, big_n) - fill
    lo, hi = 1e-6, 1.0
    while covered(hi) > 0:
        hi *= 4.0
    if covered(lo) < 0:
        return lo
    return float(brentq(covered, lo, hi, xtol=1e-10))


def _sample(region, count: int, rng: np.random.Generator) -> np.ndarray:
    """Uniform random points in a polygonal region (constrained Delaunay triangles)."""
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(region))
    corners = shapely.get_coordinates(tris).reshape(len(tris), 4, 2)[:, :3]
    d1, d2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    areas = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    pick = rng.choice(len(tris), size=count, p=areas / areas.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return corners[pick, 0] + u[:, None] * d1[pick] + v[:, None] * d2[pick]


def randomized_fractals(region: Polygon, radii: np.ndarray, rng: np.random.Generator,
                        config: FractalConfig | None = None) -> np.ndarray:
    """Algorithm 2: random placement of coverage circles of ``radii`` in ``region``.

    Returns (n, 2) centres in the order of ``radii``. Raises PartitionError when the
    free space is full, with the area needed and the scale factor to apply.
    """
    config = config or FractalConfig()
    radii = np.asarray(radii, dtype=float)
    n = len(radii)
    check_fits(region.area, radii)
    big_n = schedule_offset(n, config.c, config.fill)
    claims = np.sqrt(zeta_areas(region.area, n, config.c, big_n) / np.pi)
    # Largest circles first, ties in seeded random order.
    order = np.lexsort((rng.random(n), -radii))
    inner = {float(r): region.buffer(-float(r) * (1 + 1e-6) - 1e-9) for r in np.unique(radii)}
    centres = np.empty((0, 2))
    reach = np.empty(0)          # claimed radius of each placed circle
    out = np.empty((n, 2))
    for k, i in enumerate(order):
        r = float(radii[i])
        placed = None
        for claim in (max(claims[k], r), r):
            placed = _place(inner[r], centres, reach, claim, rng, config)
            if placed is not None:
                break
        if placed is None:
            done = radii[order[:k]]
            factor = float(np.sum(radii ** 2) / max(np.sum(done ** 2), 1e-12))
            raise PartitionError(
                f'randomized fractals: the free space is full after {k} of {n} coverage '
                f'circles in a shape of {region.area:.3g} m^2; make the shape about '
                f'{factor:.2g} times larger in area (scale by {np.sqrt(factor):.2g}) or use '
                'bubble packing')
        out[i] = placed
        centres = np.vstack([centres, placed])
        reach = np.append(reach, claim)
    return out


def _place(zone, centres: np.ndarray, reach: np.ndarray, claim: float,
           rng: np.random.Generator, config: FractalConfig) -> np.ndarray | None:
    """A random point of ``zone`` at least claim + reach_j from every placed centre."""
    if zone.is_empty:
        return None
    for _ in range(config.tries):
        cand = _sample(zone, config.batch, rng)
        if not len(centres):
            return cand[0]
        dist = np.linalg.norm(cand[:, None, :] - centres[None, :, :], axis=2)
        ok = np.flatnonzero((dist >= reach[None, :] + claim).all(axis=1))
        if len(ok):
            return cand[ok[0]]
    # Exact free configuration space: empty means full (Algorithm 2's break).
    disks = shapely.buffer(shapely.points(centres), (reach + claim) * 1.005, quad_segs=8)
    free = zone.difference(shapely.union_all(disks))
    if free.is_empty or free.area <= 0:
        return None
    return _sample(free, 1, rng)[0]


