"""Free configuration space of an agent type (thesis 3.2.2.2, eqs. 3.102-3.103).

The forbidden space is the Minkowski sum of every workspace obstacle with the agent's
coverage disc. For a disc that sum is exactly a shapely buffer by r; we buffer by
R = r / cos(pi / 4q) with q segments per quarter circle, so the chords of every rounded
corner are tangent to the true arc and the grown obstacles contain the exact Minkowski
sum (paths that avoid them are collision free) while keeping few vertices for the
visibility graph. The price: straight edges move out by R, not r (8 % of r for q = 2),
and a grown square's area lies between s^2 + 4 s r + pi r^2 and s^2 + 4 s R + pi R^2.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

QUAD_SEGS = 2  # segments per quarter circle of the grown corners


class FreeSpaceError(ValueError):
    """A point of interest inside the forbidden space, or an unusable obstacle."""


def grow_obstacles(obstacles: Sequence[Polygon], radius: float,
                   quad_segs: int = QUAD_SEGS) -> list[Polygon]:
    """Obstacles grown by a disc of ``radius`` (eq. 3.103); overlapping ones merged."""
    if radius < 0 or not math.isfinite(radius):
        raise FreeSpaceError(f'coverage radius must be finite and >= 0, got {radius}')
    if not obstacles:
        return []
    grown = [shapely.buffer(o, _circumscribed(radius, quad_segs), quad_segs=quad_segs)
             for o in obstacles if o is not None and not o.is_empty]
    return merge(grown)


def grow_discs(centres, radii, quad_segs: int = QUAD_SEGS) -> list[Polygon]:
    """Discs of ``radii`` (k,) round ``centres`` (k, 2) as polygons that contain them,
    with the corners of ``grow_obstacles``: for another robot of cover r_j, grown by this
    robot's r_i (eq. 3.103 for a disc obstacle), the radius is r_i + r_j."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    if not len(centres):
        return []
    radii = np.asarray(radii, dtype=float).reshape(-1)
    outer = [_circumscribed(float(r), quad_segs) for r in radii]
    return list(shapely.buffer(shapely.points(centres), outer, quad_segs=quad_segs))


def merge(polygons: Sequence[Polygon]) -> list[Polygon]:
    """The polygons with overlapping ones merged."""
    merged = shapely.union_all(list(polygons))
    if isinstance(merged, Polygon):
        return [merged]
    if isinstance(merged, MultiPolygon):
        return list(merged.geoms)
    return [g for g in getattr(merged, 'geoms', []) if isinstance(g, Polygon)]


def _circumscribed(radius: float, quad_segs: int) -> float:
    """R = r / cos(pi / 4q): the chords of a buffer by R are tangent to the circle of r."""
    return radius / math.cos(math.pi / (4 * quad_segs)) if radius > 0 else 0.0


def free_space(workspace: Polygon, obstacles: Sequence[Polygon], radius: float) -> Polygon:
    """The workspace shrunk by the radius minus the grown obstacles (eq. 3.102)."""
    inner = workspace.buffer(-radius)
    grown = grow_obstacles(obstacles, radius)
    return inner.difference(shapely.union_all(grown)) if grown else inner


def check_free(point, grown: Sequence[Polygon], what: str = 'point') -> None:
    """Raise FreeSpaceError if ``point`` lies inside a grown obstacle, saying how far out."""
    p = shapely.Point(float(point[0]), float(point[1]))
    for k, obstacle in enumerate(grown):
        if obstacle.contains(p):
            depth = obstacle.exterior.distance(p)
            raise FreeSpaceError(
                f'{what} ({p.x:.2f}, {p.y:.2f}) is inside grown obstacle {k}; move it at '
                f'least {depth:.2f} m out of the obstacle')
