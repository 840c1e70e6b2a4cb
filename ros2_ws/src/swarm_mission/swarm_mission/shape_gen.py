"""Seeded procedural formation shapes nobody tuned for (the generalization study).

The thesis judges its methods on a handful of hand-picked contours (chapter 4); a user's
own shape is always an unseen one. ``generate(kind, seed, n_agents)`` draws one shape of
a kind, sized to the swarm as in the thesis (``AREA_PER_AGENT`` = 314 m^2 / 50 robots,
about 6.3 m^2 a robot) and placed as the thesis shapes are (area centroid at the origin
of the +/-50 m workspace in which ``swarm_common.fleet.random_fleet`` scatters the robots):

=============  ====================================================================
``blob``       star-convex contour r(theta) = 1 + sum_k a_k cos(k theta + phi_k),
               stretched and turned at random
``concave``    a band 4.5-7 m wide (narrower for small swarms, >= 2.5 m) along a
               polyline of 3-5 segments turning 50-130 degrees (mitred corners),
               filling at most 85 % of its convex hull
``spiral``     a band 4-5.5 m wide along an Archimedean spiral, turns 2.5-4 m apart
``holes``      a mild blob with 1-3 blob-shaped holes, every passage >= 2.2 m wide
``neck``       two blobs joined by a corridor about two coverage diameters of the
               largest robot wide (2 m for the thesis's type 3, r = 0.5 m)
``obstacles``  a blob or concave shape with 2-4 workspace obstacles (walls, boxes,
               triangles) 3-8 m outside it, between the robots' start area and the
               shape, at least 3 m from each other and from the shape
=============  ====================================================================

Every shape is a valid :class:`~swarm_common.shapes.Shape` (built through
``shape_from_polygon``) of the target area (within 1e-6; the tests allow 10 %) that the
thesis swarm of ``n_agents`` can cover (``swarm_mission.coverability``); a draw that is
not is redrawn from the same generator, so a (kind, seed) pair always gives the same
shape. ``study_shapes(n, seed)`` cycles through the kinds.
"""

from __future__ import annotations

from collections.abc import Callable
import math

import numpy as np
from scipy.optimize import brentq
import shapely
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon

from swarm_common.builtin_shapes import THESIS_AREA
from swarm_common.robot_types import default_type_counts, load_robot_types
from swarm_common.shapes import Shape, shape_from_polygon, ShapeError
from swarm_mission.coverability import coverability_problem

KINDS = ('blob', 'concave', 'spiral', 'holes', 'neck', 'obstacles')
THESIS_AGENTS = 50
AREA_PER_AGENT = THESIS_AREA / THESIS_AGENTS   # m^2 per robot, chapter 4
WORKSPACE_HALF_SIZE = 50.0                     # m, random_fleet's default
EDGE_CLEARANCE = 5.0            # m a shape (and its obstacles) keeps from the workspace edge
OBSTACLE_CLEARANCE = 3.0        # m between obstacles, and from obstacles to the shape
MIN_PASSAGE = 2.2               # m, narrowest passage around holes
MIN_BAND = 2.5                  # m, narrowest concave band (small swarms)
MAX_DRAWS = 50
CONCAVITY = 0.85               # a concave shape fills at most this share of its hull


class ShapeGenError(ShapeError):
    """A shape kind or size the generator cannot draw."""


def target_area(n_agents: int) -> float:
    """The formation area for ``n_agents`` robots at the thesis density, m^2."""
    return AREA_PER_AGENT * n_agents


def neck_width() -> float:
    """Two coverage diameters of the largest robot type (Table 4.1: 4 x 0.5 m = 2 m)."""
    return 4.0 * max(t.coverage_radius for t in load_robot_types().values())


# ---------------------------------------------------------------- building blocks

def _star(rng: np.random.Generator, roughness: float, harmonics: int = 5,
          n: int = 96) -> np.ndarray:
    """A star-convex ring of mean radius 1: r = 1 + sum_{k=2..H} a_k cos(k t + phi_k)."""
    t = 2 * np.pi * np.arange(n) / n
    wave = np.zeros(n)
    for k in range(2, harmonics + 1):
        wave += rng.uniform(0.0, roughness) / k * np.cos(k * t + rng.uniform(0, 2 * np.pi))
    # Deep valleys are kept to 40 % of the mean radius: no spike thinner than a robot.
    r = 1.0 + wave * min(1.0, 0.6 / max(1e-9, -wave.min()))
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def _fit(build: Callable[[float], Polygon], area: float, lo: float, hi: float) -> Polygon:
    """``build(x)`` for the x in [lo, hi] that gives ``area`` (area increasing in x)."""
    x = brentq(lambda v: build(v).area - area, lo, hi, xtol=1e-9, rtol=1e-12)
    return build(x)


def _scaled_to(poly: Polygon, area: float) -> Polygon:
    k = math.sqrt(area / poly.area)
    return affinity.scale(poly, k, k, origin='centroid')


def _blob(rng: np.random.Generator, area: float, roughness: tuple = (0.3, 0.9)) -> Polygon:
    ring = _star(rng, rng.uniform(*roughness))
    poly = affinity.scale(Polygon(ring), rng.uniform(1.0, 1.8), 1.0)
    return _scaled_to(affinity.rotate(poly, rng.uniform(0, 360)), area)


def _concave(rng: np.random.Generator, area: float) -> Polygon:
    """A thick polyline; a draw that folds into a nearly convex lump is drawn again."""
    for _ in range(MAX_DRAWS):
        width = max(MIN_BAND, rng.uniform(4.5, 7.0) * math.sqrt(area / THESIS_AREA))
        heading = rng.uniform(0, 2 * np.pi)
        steps = [np.zeros(2)]
        for _ in range(int(rng.integers(3, 6))):
            steps.append(steps[-1] + rng.uniform(0.6, 1.4) * np.array(
                [math.cos(heading), math.sin(heading)]))
            heading += rng.choice([-1, 1]) * np.radians(rng.uniform(50, 130))
        unit = np.array(steps)
        length = LineString(unit).length

        def build(scale: float, unit=unit, width=width) -> Polygon:
            band = LineString(unit * scale).buffer(width / 2, cap_style='square',
                                                   join_style='mitre', mitre_limit=2.0)
            return Polygon(band.exterior.coords)   # a self-crossing band closes its loops

        poly = _fit(build, area, 0.05 * area / width / length, 3.0 * area / width / length)
        if poly.area < CONCAVITY * poly.convex_hull.area:
            return poly
    raise ShapeGenError(f'no concave polygon of {area:.0f} m^2 in {MAX_DRAWS} draws')


def _spiral(rng: np.random.Generator, area: float) -> Polygon:
    width = rng.uniform(4.0, 5.5)
    pitch = width + rng.uniform(2.5, 4.0)
    r0 = width / 2 + rng.uniform(0.5, 1.5)
    phase = rng.uniform(0, 2 * np.pi)
    turn = rng.choice([-1.0, 1.0])

    def build(theta_max: float) -> Polygon:
        theta = np.linspace(0.0, theta_max, max(8, int(theta_max * 12)))
        r = r0 + pitch * theta / (2 * np.pi)
        line = LineString(np.column_stack([r * np.cos(turn * theta + phase),
                                           r * np.sin(turn * theta + phase)]))
        return line.buffer(width / 2, cap_style='round', quad_segs=6)

    return _fit(build, area, 0.05, 40 * np.pi)


def _holes(rng: np.random.Generator, area: float) -> Polygon:
    shrink = math.sqrt(area / THESIS_AREA)
    passage = max(MIN_PASSAGE, 3.0 * shrink)
    for _ in range(MAX_DRAWS):
        outer = _blob(rng, area * rng.uniform(1.1, 1.3), roughness=(0.1, 0.3))
        inner = outer.buffer(-passage)
        if inner.is_empty:
            continue
        holes: list[Polygon] = []
        for _ in range(int(rng.integers(1, 4))):
            size = max(0.6, rng.uniform(1.5, 3.5) * shrink)
            hole = affinity.scale(Polygon(_star(rng, 0.3, n=48)), size, size, origin=(0, 0))
            hole = affinity.rotate(hole, rng.uniform(0, 360), origin=(0, 0))
            for _ in range(40):
                x0, y0, x1, y1 = inner.bounds
                c = rng.uniform([x0, y0], [x1, y1])
                placed = affinity.translate(hole, *c)
                if inner.contains(placed) and all(
                        placed.distance(h) >= passage for h in holes):
                    holes.append(placed)
                    break
        if holes:
            region = Polygon(outer.exterior.coords, [h.exterior.coords for h in holes])
            return _scaled_to(region, area)
    raise ShapeGenError(f'cannot place a hole in a {area:.0f} m^2 shape; give more agents')


def _neck(rng: np.random.Generator, area: float) -> Polygon:
    width = neck_width() * rng.uniform(1.0, 1.1)
    length = rng.uniform(2.0, 5.0)
    share = rng.uniform(0.4, 0.6)
    rings = [Polygon(_star(rng, rng.uniform(0.1, 0.3))) for _ in range(2)]
    angle = rng.uniform(0, 2 * np.pi)
    u = np.array([math.cos(angle), math.sin(angle)])

    def reach(poly: Polygon, direction: np.ndarray) -> float:
        ray = LineString([(0, 0), tuple(100 * direction)])
        return float(Point(0, 0).distance(poly.exterior.intersection(ray)))

    def build(scale: float) -> Polygon:
        a = affinity.scale(rings[0], scale * math.sqrt(share), scale * math.sqrt(share),
                           origin=(0, 0))
        b = affinity.scale(rings[1], scale * math.sqrt(1 - share),
                           scale * math.sqrt(1 - share), origin=(0, 0))
        d = reach(a, u) + length + reach(b, -u)
        b = affinity.translate(b, *(d * u))
        corridor = LineString([(0, 0), tuple(d * u)]).buffer(width / 2, cap_style='flat')
        return shapely.union_all([a, b, corridor])

    unit = math.sqrt(area / math.pi)
    return _fit(build, area, 0.2 * unit, 2.0 * unit)


def _obstacles(rng: np.random.Generator, region: Polygon) -> list[Polygon]:
    """2-4 obstacles 3-8 m outside ``region`` (centred at the origin), spread in angle."""
    reach = max(math.hypot(x, y) for x, y in region.exterior.coords)
    count = int(rng.integers(2, 5))
    start = rng.uniform(0, 2 * np.pi)
    obstacles: list[Polygon] = []
    for k in range(count):
        angle = start + 2 * np.pi * k / count + rng.uniform(-0.3, 0.3)
        u = np.array([math.cos(angle), math.sin(angle)])
        kind = rng.choice(['wall', 'box', 'triangle'])
        if kind == 'wall':
            poly = shapely.geometry.box(-rng.uniform(0.4, 1.0), -rng.uniform(4, 8),
                                        rng.uniform(0.4, 1.0), rng.uniform(4, 8))
        elif kind == 'box':
            side = rng.uniform(3.0, 6.0)
            poly = shapely.geometry.box(-side / 2, -side / 2, side / 2, side / 2)
        else:
            poly = Polygon(3.5 * np.column_stack([np.cos(2 * np.pi * np.arange(3) / 3),
                                                  np.sin(2 * np.pi * np.arange(3) / 3)]))
        poly = affinity.rotate(poly, math.degrees(angle) + rng.uniform(-20, 20),
                               origin=(0, 0))
        gap = rng.uniform(OBSTACLE_CLEARANCE, 8.0)
        # Move outward from the shape's farthest reach until the clearance holds.
        for d in np.arange(reach * 0.5, reach + 30.0, 0.5):
            placed = affinity.translate(poly, *(d * u))
            if placed.distance(region) >= gap:
                break
        if all(placed.distance(o) >= OBSTACLE_CLEARANCE for o in obstacles):
            obstacles.append(placed)
    return obstacles


# ---------------------------------------------------------------- public

def _draw(kind: str, rng: np.random.Generator, area: float) -> tuple[Polygon, list[Polygon]]:
    if kind == 'blob':
        return _blob(rng, area), []
    if kind == 'concave':
        return _concave(rng, area), []
    if kind == 'spiral':
        return _spiral(rng, area), []
    if kind == 'holes':
        return _holes(rng, area), []
    if kind == 'neck':
        return _neck(rng, area), []
    base = _blob(rng, area) if rng.random() < 0.5 else _concave(rng, area)
    c = base.centroid
    base = affinity.translate(base, -c.x, -c.y)
    return base, _obstacles(rng, base)


def generate(kind: str, seed: int, n_agents: int = THESIS_AGENTS) -> Shape:
    """One shape of ``kind`` (see ``KINDS``) for a thesis swarm of ``n_agents``.

    Deterministic in (kind, seed); named ``<kind>_<seed>``. The area is
    ``target_area(n_agents)``, the area centroid is the origin, and the shape and its
    obstacles keep ``EDGE_CLEARANCE`` from the +/-50 m workspace edge. Raises
    ShapeGenError for an unknown kind or a swarm too small to draw the kind for.
    """
    if kind not in KINDS:
        raise ShapeGenError(f'unknown shape kind {kind!r}; use one of {", ".join(KINDS)}')
    if not (isinstance(n_agents, (int, np.integer)) and n_agents >= 1):
        raise ShapeGenError(f'n_agents must be a positive integer, got {n_agents!r}')
    area = target_area(int(n_agents))
    counts = default_type_counts(int(n_agents))
    radii = {t: r.coverage_radius for t, r in load_robot_types().items()}
    rng = np.random.default_rng((int(seed), KINDS.index(kind)))
    name = f'{kind}_{seed}'
    limit = WORKSPACE_HALF_SIZE - EDGE_CLEARANCE
    problem = ''
    for _ in range(MAX_DRAWS):
        try:
            region, obstacles = _draw(kind, rng, area)
        except ValueError as exc:   # brentq: no size of this draw reaches the area
            problem = str(exc) or f'no {kind} of {area:.0f} m^2'
            continue
        c = region.centroid
        region = affinity.translate(region, -c.x, -c.y)
        obstacles = [affinity.translate(o, -c.x, -c.y) for o in obstacles]
        if not region.is_valid or not isinstance(region, Polygon):
            problem = 'an invalid outline'
            continue
        bounds = shapely.union_all([region, *obstacles]).bounds
        if max(abs(v) for v in bounds) > limit:
            problem = f'a shape reaching beyond +/-{limit:g} m'
            continue
        shape = shape_from_polygon(region, obstacles, name=name)
        problem = coverability_problem(shape, counts, radii) or ''
        if not problem:
            return shape
    raise ShapeGenError(f'{name}: no coverable shape in {MAX_DRAWS} draws for {n_agents} '
                        f'agents (last: {problem})')


def study_shapes(n: int, seed: int, n_agents: int = THESIS_AGENTS) -> list[Shape]:
    """``n`` shapes cycling through ``KINDS``; shape i uses seed ``seed * 1000 + i // 6``."""
    return [generate(KINDS[i % len(KINDS)], seed * 1000 + i // len(KINDS), n_agents)
            for i in range(n)]
