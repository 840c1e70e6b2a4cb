"""Up-front check that a swarm can cover a formation shape at all.

A shape is refused, with one line naming the reason and the fix, when

- its area is smaller than the swarm's coverage discs: the thesis asks every robot to
  cover its own disc of radius r_i inside the shape (3.2.2.1), so the region must hold
  at least sum(pi r_i^2) m^2 (non-overlapping discs cannot cover more area than the
  region has; the check refuses only shapes that certainly fail);
- some of it is unreachable behind workspace obstacles: in the free space of the largest
  robot type present (obstacles grown by its coverage radius, eqs. 3.102-3.103) the
  region and the start area (the workspace, or the given start positions) must form one
  connected piece;
- it has a neck narrower than a robot: shrunk by the largest coverage radius (the
  centres where that robot's disc fits inside the shape) it vanishes or splits into
  parts that robot cannot pass between inside the shape.

``coverability_problem`` returns the reason or None; ``check_coverable`` raises
:class:`~swarm_common.shapes.ShapeError` with it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math

import numpy as np
import shapely
from shapely.geometry import box, MultiPolygon, Polygon
from shapely.ops import nearest_points

from swarm_common.shapes import Shape, ShapeError

WORKSPACE_HALF_SIZE = 50.0  # m, the thesis workspace (swarm_common.fleet.random_fleet)
START_MARGIN = 1.0          # m, random_fleet keeps robots this far from obstacles
AREA_TOLERANCE = 1e-6       # m^2, geometry noise below which a piece is ignored


def _polygons(geometry) -> list[Polygon]:
    """The polygons of a (multi)polygon or collection, largest first."""
    if geometry is None or geometry.is_empty:
        return []
    parts = [geometry] if isinstance(geometry, Polygon) else [
        g for g in getattr(geometry, 'geoms', []) if isinstance(g, Polygon)]
    return sorted((p for p in parts if p.area > AREA_TOLERANCE), key=lambda p: -p.area)


def _xy(x: float, y: float) -> str:
    """``(x, y)`` to 0.1 m, without a negative zero."""
    return f'({round(x, 1) + 0.0:.1f}, {round(y, 1) + 0.0:.1f})'


def _where(geometry) -> str:
    p = geometry.representative_point()
    return _xy(p.x, p.y)


def required_area(type_counts: Mapping[int, int], radii: Mapping[int, float]) -> float:
    """Sum of pi r^2 over the swarm's coverage discs, m^2."""
    return float(sum(int(c) * math.pi * float(radii[t]) ** 2
                     for t, c in type_counts.items() if c > 0))


def largest_radius(type_counts: Mapping[int, int], radii: Mapping[int, float]) -> float:
    """The coverage radius of the largest robot type present in the swarm, m."""
    present = [float(radii[t]) for t, c in type_counts.items() if c > 0]
    return max(present) if present else 0.0


def _area_problem(shape: Shape, type_counts: Mapping[int, int],
                  radii: Mapping[int, float]) -> str | None:
    need = required_area(type_counts, radii)
    if shape.area >= need:
        return None
    n = sum(c for c in type_counts.values() if c > 0)
    return (f'shape {shape.name!r} is too small: {shape.area:.3g} m^2 cannot hold the '
            f'coverage discs of {n} robots ({need:.3g} m^2, the sum of pi r^2); scale it '
            f'up by at least {math.sqrt(need / shape.area):.2f} or use fewer robots')


def _reach_problem(shape: Shape, radius: float, starts: np.ndarray | None,
                   half_size: float) -> str | None:
    if not shape.obstacles:
        return None
    # The Minkowski sum of each obstacle with the robot's disc (eq. 3.103): a gap
    # narrower than 2 r closes.
    blocked = shapely.union_all([o.buffer(radius) for o in shape.obstacles])
    region_free = shape.region.difference(blocked)
    if region_free.area <= AREA_TOLERANCE:
        return (f'shape {shape.name!r} lies entirely inside the workspace obstacles (grown '
                f'by the {radius:g} m coverage radius); move the shape or the obstacles')
    workspace = box(-half_size, -half_size, half_size, half_size)
    travel = shapely.union_all([workspace, shape.region]).convex_hull.buffer(radius)
    pieces = _polygons(travel.difference(blocked))
    holding = [p for p in pieces if p.intersection(region_free).area > AREA_TOLERANCE]
    if len(holding) > 1:
        main = holding[0]
        cut = region_free.difference(main)
        return (f'shape {shape.name!r}: {cut.area:.3g} m^2 of the region around '
                f'{_where(cut)} is walled off from the rest by obstacles (for a robot of '
                f'coverage radius {radius:g} m); open a gap wider than {2 * radius:g} m or '
                'move the obstacles')
    main = holding[0]
    if starts is not None:
        for k, p in enumerate(np.asarray(starts, dtype=float).reshape(-1, 2)):
            point = shapely.Point(p)
            if blocked.contains(point):
                continue      # a robot pressed against an obstacle: judged by the sim
            if not main.buffer(1e-9).contains(point):
                return (f'shape {shape.name!r} is unreachable behind obstacles from the '
                        f'start position {k} at {_xy(*p)} (robot of '
                        f'coverage radius {radius:g} m); open a gap wider than '
                        f'{2 * radius:g} m or move the obstacles')
        return None
    startable = workspace.difference(shapely.union_all(
        [o.buffer(START_MARGIN) for o in shape.obstacles]))
    for piece in pieces:
        if piece is main:
            continue
        pocket = piece.intersection(startable)
        if pocket.area > AREA_TOLERANCE:
            return (f'shape {shape.name!r} is unreachable behind obstacles: robots starting '
                    f'in the {piece.area:.3g} m^2 of workspace around {_where(pocket)} are '
                    f'walled off from it (for a robot of coverage radius {radius:g} m); '
                    f'open a gap wider than {2 * radius:g} m or move the obstacles')
    return None


def _neck_problem(shape: Shape, radius: float) -> str | None:
    core = shape.region.buffer(-radius)
    parts = _polygons(core)
    if not parts:
        return (f'shape {shape.name!r} vanishes when shrunk by the largest coverage radius '
                f'{radius:g} m: it is nowhere {2 * radius:g} m wide, narrower than a robot; '
                'widen it')
    if len(parts) == 1:
        return None
    rest = shapely.union_all(parts[:-1])
    a, b = nearest_points(parts[-1], rest)
    areas = ', '.join(f'{p.area:.3g}' for p in parts)
    return (f'shape {shape.name!r} has a neck narrower than a robot ({2 * radius:g} m, the '
            f'largest coverage diameter) near {_xy((a.x + b.x) / 2, (a.y + b.y) / 2)}: '
            f'shrunk by {radius:g} m it splits into {len(parts)} parts ({areas} m^2); '
            'widen the neck')


def coverability_problem(shape: Shape, type_counts: Mapping[int, int],
                         radii: Mapping[int, float], *,
                         starts: Sequence[Sequence[float]] | np.ndarray | None = None,
                         half_size: float = WORKSPACE_HALF_SIZE) -> str | None:
    """Why the swarm ``type_counts`` ({type: count}) cannot cover ``shape``, or None.

    ``radii`` maps robot type to coverage radius (Table 4.1). ``starts`` are the robots'
    start positions; without them the start area is the +/-``half_size`` m workspace
    minus the obstacles (where ``random_fleet`` places robots).
    """
    if not isinstance(shape.region, Polygon) or isinstance(shape.region, MultiPolygon):
        return f'shape {shape.name!r} must be one polygon'
    problem = _area_problem(shape, type_counts, radii)
    if problem:
        return problem
    radius = largest_radius(type_counts, radii)
    if radius <= 0.0:
        return None
    starts_arr = None if starts is None else np.asarray(starts, dtype=float)
    return (_reach_problem(shape, radius, starts_arr, half_size)
            or _neck_problem(shape, radius))


def check_coverable(shape: Shape, type_counts: Mapping[int, int],
                    radii: Mapping[int, float], **kwargs) -> None:
    """Raise ShapeError (one line: the reason and the fix) if the swarm cannot cover
    ``shape``; see :func:`coverability_problem`."""
    problem = coverability_problem(shape, type_counts, radii, **kwargs)
    if problem:
        raise ShapeError(problem)
