"""Bubble packing partition of a formation shape (thesis 3.2.2.1, Algorithm 1, eqs. 3.95-3.98).

One bubble per agent, radius = the agent's coverage radius. Two stages:

1. ``initial_placement`` (Algorithm 1, INITIALIZE_BUBBLE_POSITIONS): bubbles in a seeded
   random order, each put at the point of its free configuration space closest to the
   shape centre; every placed bubble becomes an obstacle for the next. The free space
   is the region eroded by the bubble's radius minus disks of radius
   max(spacing, r_i + r_j) around the placed bubbles (shapely buffers/differences).
2. ``relax`` (the meshing process): interbubble forces (eq. 3.95) between neighbour
   pairs (scipy.spatial.cKDTree) and shape repulsion, integrated as an over-damped
   system until the largest step falls below a tolerance; circles are kept inside the
   shape by projection onto the eroded region (a hard constraint added to the thesis's
   soft repulsion so that every goal is feasible).

Force laws (``BubbleConfig.force``):

- ``'thesis'``: eq. 3.95 with l in metres, a=-0.1, b=-0.2, c=-0.3, d=4, l0=2.5 m. It is
  0.44 at l0 and 0 beyond: purely repulsive with a jump (DESIGN.md).
- ``'shimada'`` (default): the same cubic on the normalised distance w = l / l_ij,
  Shimada and Gossard's coefficients a=1.25, b=-2.375, c=0, d=1.125, cut off at
  w=1.5: repulsive below the target distance l_ij, weakly attractive up to 1.5 l_ij,
  zero force and a stable equilibrium at l_ij.

Shape repulsion (``BubbleConfig.boundary``):

- ``'layer'`` (default): the boundary row lies on the contour. Every bubble is kept in
  the boundary layer, the shape eroded by the largest coverage radius r_max (the closest
  one common row can come to the contour with every circle inside), as a hard
  constraint in place of a repulsion: the lattice pressure of eq. 3.95 presses the
  outer bubbles onto that offset curve. Why (issue 4, measured on thesis_shape_3/_4):
  with the boundary row held half a spacing inside (``'mirror'``), or at each bubble's
  own radius, the outer nodes form a wavy or concave row whose Delaunay hull triangles
  (three boundary nodes bridging a concavity, a hole corner or a dent of the row) have
  their centroids inside the shape; those slivers (r/R near 0) made most of epsilon_g
  (eq. 3.106) and turned boundary nodes of degree 4-5 into "interior" nodes for
  epsilon_t (eq. 3.104). A row on one common offset curve leaves such triangles outside
  the shape. Running longer (tolerance 1e-4, 3000 iterations) or changing the spacing by
  5 % did not remove them.
- ``'mirror'``: the interbubble law on each bubble's mirror image in the nearest
  boundary point, which settles the boundary row half a spacing from the boundary. It
  was the default while the running system partitioned the shape itself: robots park
  within about a metre of their goals (0.3 m hold, 0.8 m resume radius, ~0.5 m
  localization error), and with the outer row only r_max inside the contour a type-1
  robot parked 0.12 m outside the shape in the 12-agent ROS e2e (2 runs of 2). The
  running system now partitions the shape shrunk by a localization margin
  (``partition(..., margin=)``, mission ``formation_margin_m``), which keeps that
  safety band without giving up the mesh.
- ``'thesis'``: eq. 3.97, k_r sum_k (x_i - z_k) / |x_i - z_k|^3 dz over equally spaced
  boundary samples (eq. 3.98).

Spacing (``BubbleConfig.spacing``): ``'auto'`` derives the target distance from the
region and the number of agents, never below r_i + r_j. With ``'layer'`` the nodes fill
the layer with B of them on its boundary: Pick's theorem on the triangular lattice,
A_layer = (n - B/2 - chi) sqrt(3)/2 l^2 with B = P_layer / l (``lattice_spacing``).
Otherwise the boundary row sits half a spacing inside and the hexagonal cells tile the
shape, l = sqrt(2 A / (sqrt(3) n)) (``auto_spacing``). ``'thesis'`` uses l0.

Incremental mode (``relax`` from previous positions, thesis 4.3.4): the previous goals
are projected into the changed shape and re-meshed from there; when that leaves circles
overlapping or outside (previous goals that crowd onto a few points of a shape they
barely overlap), the bubbles are placed afresh by Algorithm 1.
"""

from __future__ import annotations

from dataclasses import dataclass
import logging

import numpy as np
from scipy.spatial import cKDTree
import shapely
from shapely.geometry import Point, Polygon
from shapely.ops import nearest_points

from swarm_common.goals import check_fits, PartitionError, placement_violations
from swarm_mission.contour import sample_boundary

LOG = logging.getLogger(__name__)


@dataclass
class BubbleConfig:
    """Bubble packing parameters; thesis values from chapter 4 (YAML: config/partition.yaml)."""

    force: str = 'shimada'          # 'shimada' | 'thesis' (eq. 3.95 in metres)
    spacing: str = 'auto'           # 'auto' (from area and agents) | 'thesis' (l0)
    boundary: str = 'layer'         # 'layer' | 'mirror' | 'thesis' (eq. 3.97)
    a: float = -0.1                 # eq. 3.95, thesis chapter 4
    b: float = -0.2
    c: float = -0.3
    d: float = 4.0
    l0: float = 2.5                 # m
    spacing_factor: float = 1.0     # auto spacing multiplier
    k_r: float = 0.05               # eq. 3.97 gain (boundary='thesis'), per metre of contour
    contour_step: float = 0.0       # eq. 3.98 sample spacing; 0: spacing / 8
    step: float = 0.15              # over-damped step, in spacings per unit force
    max_step: float = 0.2           # largest move per iteration, in spacings
    max_iterations: int = 500
    tolerance: float = 2e-3         # converged when every step < tolerance * spacing
    shuffle: bool = True            # Algorithm 1: seeded random bubble order

    def __post_init__(self) -> None:
        checks = {'force': self.force in ('shimada', 'thesis'),
                  'spacing': self.spacing in ('auto', 'thesis'),
                  'boundary': self.boundary in ('layer', 'mirror', 'thesis'),
                  'l0': self.l0 > 0, 'spacing_factor': self.spacing_factor > 0,
                  'step': self.step > 0, 'max_step': self.max_step > 0,
                  'max_iterations': self.max_iterations >= 0, 'tolerance': self.tolerance > 0,
                  'contour_step': self.contour_step >= 0}
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise PartitionError(f'bad bubble packing parameters {bad}: forces are shimada|'
                                 'thesis, spacing auto|thesis, boundary layer|mirror|'
                                 'thesis, '
                                 'lengths and steps positive')


SHIMADA = (1.25, -2.375, 0.0, 1.125, 1.5)   # a, b, c, d, cut-off in target distances


def interbubble_force(length: np.ndarray, a: float, b: float, c: float, d: float,
                      cutoff: float) -> np.ndarray:
    """Eq. 3.95: a l^3 + b l^2 + c l + d for 0 <= l <= cutoff, else 0 (positive = repulsive)."""
    ell = np.asarray(length, dtype=float)
    return np.where((ell >= 0) & (ell <= cutoff), ((a * ell + b) * ell + c) * ell + d, 0.0)


def auto_spacing(area: float, n: int, factor: float = 1.0) -> float:
    """Side of the hexagonal lattice whose n cells cover ``area``: sqrt(2 A / (sqrt(3) n))."""
    return factor * float(np.sqrt(2.0 * area / (np.sqrt(3.0) * max(n, 1))))


def lattice_spacing(area: float, perimeter: float, n: int, euler: int = 1) -> float:
    """Side l of the triangular lattice of ``n`` nodes filling a region, B of them on its boundary.

    Pick's theorem on the triangular lattice (cell sqrt(3)/2 l^2, B = perimeter / l,
    I = n - B, ``euler`` = components - holes): area = (I + B/2 - euler) sqrt(3)/2 l^2,
    a quadratic in l.
    """
    m = max(n - euler, 1)
    root = np.sqrt(3 / 16 * perimeter ** 2 + 2 * np.sqrt(3) * m * area)
    return float((np.sqrt(3) / 4 * perimeter + root) / (np.sqrt(3) * m))


def boundary_layer(region: Polygon, r_max: float):
    """Where the boundary row lies (``boundary='layer'``): ``region`` eroded by ``r_max``.

    None when nothing is left. The buffer's arcs around reflex vertices are inscribed
    chords, which would let a circle of radius r_max poke out: the erosion is padded by
    1 / cos(pi / (4 quad_segs)).
    """
    layer = region.buffer(-r_max / np.cos(np.pi / 32) - 1e-9, quad_segs=8)
    return None if layer.is_empty or layer.area <= 0 else layer


def _euler(geom) -> int:
    return sum(1 - len(p.interiors) for p in getattr(geom, 'geoms', [geom]))


def _eroded(region: Polygon, radii: np.ndarray) -> dict[float, object]:
    """Region eroded by each distinct radius: where a circle of that radius fits."""
    return {float(r): region.buffer(-float(r) * (1 + 1e-6) - 1e-9) for r in np.unique(radii)}


def initial_placement(region: Polygon, radii: np.ndarray, spacing: float,
                      rng: np.random.Generator, *, shuffle: bool = True,
                      fixed: np.ndarray | None = None,
                      fixed_radii: np.ndarray | None = None) -> np.ndarray | None:
    """Algorithm 1 (INITIALIZE_BUBBLE_POSITIONS); None when the free space runs out.

    Bubbles are taken in a seeded random order (``shuffle``) and each is put at the point
    of its free configuration space closest to the area centroid of the shape; placed
    bubbles (and ``fixed`` ones, for incremental re-meshing) are obstacles for the rest.
    """
    radii = np.asarray(radii, dtype=float)
    n = len(radii)
    centre = region.centroid
    inner = _eroded(region, radii)
    r_max = float(radii.max()) if n else 0.0
    if fixed is not None and len(fixed):
        r_max = max(r_max, float(np.max(fixed_radii)))
    shared = spacing >= 2 * r_max
    blocked: dict[float, object] = {}

    def block(p: np.ndarray, r_j: float) -> None:
        keys = [None] if shared else list(inner)
        for key in keys:
            rad = spacing if key is None else max(spacing, key + r_j)
            disk = Point(p).buffer(rad * 1.005, quad_segs=8)   # inscribed polygon: pad
            blocked[key] = disk if key not in blocked else blocked[key].union(disk)

    for p, r in zip(np.asarray(fixed if fixed is not None else np.zeros((0, 2))),
                    np.asarray(fixed_radii if fixed_radii is not None else [])):
        block(p, float(r))
    order = rng.permutation(n) if shuffle else np.arange(n)
    out = np.empty((n, 2))
    for i in order:
        free = inner[float(radii[i])]
        key = None if shared else float(radii[i])
        if key in blocked:
            free = free.difference(blocked[key])
        if free.is_empty:
            return None
        q = nearest_points(free, centre)[0]
        out[i] = (q.x, q.y)
        block(out[i], float(radii[i]))
    return out


def _project_inside(x: np.ndarray, radii: np.ndarray, inner: dict[float, object]) -> None:
    """Move circles that stick out of the region onto the nearest point where they fit."""
    for r, zone in inner.items():
        idx = np.flatnonzero(radii == r)
        if not len(idx) or zone.is_empty:
            continue
        ok = shapely.contains_xy(zone, x[idx, 0], x[idx, 1])
        bad = idx[~ok]
        if len(bad):
            lines = shapely.shortest_line(shapely.points(x[bad]), zone)
            x[bad] = shapely.get_coordinates(lines).reshape(-1, 2, 2)[:, 1]


def _project_into(x: np.ndarray, zone) -> None:
    """Move the points outside ``zone`` onto its nearest boundary point."""
    bad = np.flatnonzero(~shapely.contains_xy(zone, x[:, 0], x[:, 1]))
    if len(bad):
        lines = shapely.shortest_line(shapely.points(x[bad]), zone.boundary)
        x[bad] = shapely.get_coordinates(lines).reshape(-1, 2, 2)[:, 1]


def _pair_targets(radii: np.ndarray, pairs: np.ndarray, spacing: float) -> np.ndarray:
    return np.maximum(spacing, radii[pairs[:, 0]] + radii[pairs[:, 1]])


def relax(region: Polygon, x0: np.ndarray, radii: np.ndarray, spacing: float,
          config: BubbleConfig, layer=None) -> tuple[np.ndarray, int, bool]:
    """Bubble meshing process: integrate eq. 3.95 + shape repulsion to equilibrium.

    With ``layer`` (``boundary='layer'``, see ``boundary_layer``) there is no repulsion
    from the contour: every step is projected into the layer, so the outer bubbles end on
    one offset curve. Returns (positions, iterations, converged).
    """
    x = np.array(x0, dtype=float)
    radii = np.asarray(radii, dtype=float)
    n = len(x)
    inner = _eroded(region, radii)
    _project_inside(x, radii, inner)
    if n == 0:
        return x, 0, True
    if config.force == 'thesis':
        a, b, c, d, cutoff = config.a, config.b, config.c, config.d, config.l0
        reach = config.l0
    else:
        a, b, c, d, cutoff = SHIMADA
        reach = cutoff * max(spacing, 2 * float(radii.max()))
    samples = None
    if config.boundary == 'thesis':
        step = config.contour_step or spacing / 8
        samples = sample_boundary(region, step)
        ds = step
    boundary = region.boundary
    move_scale = config.step * spacing
    limit = config.max_step * spacing
    quiet = 0
    iterations = 0
    converged = False
    while iterations < config.max_iterations:
        iterations += 1
        force = np.zeros_like(x)
        pairs = cKDTree(x).query_pairs(reach, output_type='ndarray') if n > 1 else \
            np.zeros((0, 2), dtype=int)
        if len(pairs):
            delta = x[pairs[:, 0]] - x[pairs[:, 1]]
            dist = np.linalg.norm(delta, axis=1)
            dist = np.maximum(dist, 1e-9)
            if config.force == 'thesis':
                mag = interbubble_force(dist, a, b, c, d, cutoff)
            else:
                mag = interbubble_force(dist / _pair_targets(radii, pairs, spacing),
                                        a, b, c, d, cutoff)
            f = (mag / dist)[:, None] * delta
            np.add.at(force, pairs[:, 0], f)
            np.add.at(force, pairs[:, 1], -f)
        if layer is not None:
            pass     # hard constraint below, no shape force
        elif samples is None:
            # Mirror image across the nearest boundary point: same law at distance 2 d.
            pts = shapely.points(x)
            near = shapely.get_coordinates(shapely.shortest_line(pts, boundary)).reshape(-1, 2,
                                                                                        2)[:, 1]
            delta = x - near
            dist = np.maximum(np.linalg.norm(delta, axis=1), 1e-9)
            target = np.maximum(spacing, 2 * radii)
            if config.force == 'thesis':
                mag = interbubble_force(2 * dist, a, b, c, d, cutoff)
            else:
                mag = np.where(2 * dist < target, interbubble_force(2 * dist / target,
                                                                    a, b, c, d, 1.0), 0.0)
            force += (mag / dist)[:, None] * delta
        else:
            # Eq. 3.97 summed over samples (chunked to bound memory).
            rows = max(1, 2_000_000 // len(samples))
            for s in range(0, n, rows):
                diff = x[s:s + rows, None, :] - samples[None, :, :]
                r3 = np.maximum(np.linalg.norm(diff, axis=2), 1e-6) ** 3
                force[s:s + rows] += config.k_r * ds * (diff / r3[:, :, None]).sum(axis=1)
        move = move_scale * force
        norm = np.linalg.norm(move, axis=1)
        too_far = norm > limit
        move[too_far] *= (limit / norm[too_far])[:, None]
        x_new = x + move
        if layer is not None:
            _project_into(x_new, layer)
        _project_inside(x_new, radii, inner)
        biggest = float(np.abs(x_new - x).max())
        x = x_new
        quiet = quiet + 1 if biggest < config.tolerance * spacing else 0
        if quiet >= 5:
            converged = True
            break
    return x, iterations, converged


def separate(region: Polygon, x: np.ndarray, radii: np.ndarray,
             rounds: int = 50) -> np.ndarray:
    """Push overlapping circles apart (and back inside) until no pair overlaps."""
    x = np.array(x, dtype=float)
    inner = _eroded(region, radii)
    for _ in range(rounds):
        outside, pairs = placement_violations(x, radii, region, tol=1e-7)
        if not len(pairs) and not len(outside):
            break
        if len(pairs):
            delta = x[pairs[:, 1]] - x[pairs[:, 0]]
            dist = np.maximum(np.linalg.norm(delta, axis=1), 1e-9)
            need = radii[pairs[:, 0]] + radii[pairs[:, 1]] - dist
            push = (0.5 * (need + 1e-6) / dist)[:, None] * delta
            np.add.at(x, pairs[:, 1], push)
            np.add.at(x, pairs[:, 0], -push)
        _project_inside(x, radii, inner)
    return x


def bubble_pack(region: Polygon, radii: np.ndarray, rng: np.random.Generator,
                config: BubbleConfig | None = None,
                previous: np.ndarray | None = None,
                previous_mask: np.ndarray | None = None) -> tuple[np.ndarray, int, bool, float]:
    """Partition ``region`` for circles of ``radii``: Algorithm 1 + meshing.

    ``previous`` (n, 2) with ``previous_mask`` (n,) bool marks bubbles that start from
    previous goals (incremental re-meshing, 4.3.4); the others are placed by Algorithm 1
    around them. Returns (positions, iterations, converged, spacing). Raises
    PartitionError when the circles cannot fit, saying by how much the shape must grow.
    """
    config = config or BubbleConfig()
    radii = np.asarray(radii, dtype=float)
    n = len(radii)
    need = check_fits(region.area, radii)
    layer = boundary_layer(region, float(radii.max())) if config.boundary == 'layer' else None
    if config.spacing == 'auto' and layer is not None:
        spacing = config.spacing_factor * lattice_spacing(layer.area, layer.length, n,
                                                          _euler(layer))
    elif config.spacing == 'auto':
        spacing = auto_spacing(region.area, n, config.spacing_factor)
    else:
        spacing = config.l0
    spacing = max(spacing, 2 * float(radii.max()))
    keep = previous_mask if previous_mask is not None else np.zeros(n, dtype=bool)
    x0 = None
    trial = spacing
    for _ in range(40):
        if previous is not None and keep.any():
            start = np.array(previous, dtype=float)
            _project_inside(start, radii, _eroded(region, radii))
            rest = initial_placement(region, radii[~keep], trial, rng, shuffle=config.shuffle,
                                     fixed=start[keep], fixed_radii=radii[keep]) \
                if (~keep).any() else np.zeros((0, 2))
            if rest is not None:
                start[~keep] = rest
                x0 = start
        else:
            x0 = initial_placement(region, radii, trial, rng, shuffle=config.shuffle)
        if x0 is not None:
            break
        trial *= 0.95
    if x0 is None:
        raise PartitionError(f'cannot place {n} bubbles in a shape of {region.area:.3g} m^2; '
                             f'scale the shape by at least {np.sqrt(need / region.area):.3g}')
    if previous is not None and keep.any():
        # Coincident projected goals would have no direction to separate: jitter them.
        x0 = x0 + rng.normal(scale=1e-3 * spacing, size=x0.shape) * keep[:, None]
    x, iterations, converged = relax(region, x0, radii, spacing, config, layer=layer)
    x = separate(region, x, radii)
    outside, pairs = placement_violations(x, radii, region, tol=1e-7)
    if (len(outside) or len(pairs)) and previous is not None and keep.any():
        # Previous goals projected into a shape they barely overlap crowd onto a few
        # boundary points, which relaxation may not pull apart: the bubbles start afresh.
        LOG.info('incremental re-mesh left %d circles outside and %d overlapping pairs: '
                 'bubbles placed afresh', len(outside), len(pairs))
        return bubble_pack(region, radii, rng, config)
    if len(outside) or len(pairs):
        raise PartitionError(
            f'bubble packing left {len(outside)} circles outside and {len(pairs)} overlapping '
            f'pairs in a shape of {region.area:.3g} m^2 (circles need {need:.3g} m^2); '
            'enlarge the shape or use fewer agents')
    LOG.debug('bubble packing: %d bubbles, spacing %.3f m, %d iterations, converged %s',
              n, spacing, iterations, converged)
    return x, iterations, converged, spacing
