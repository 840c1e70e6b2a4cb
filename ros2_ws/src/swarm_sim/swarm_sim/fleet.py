"""The fleet: one source of truth for robot ids, types, beacons and deployment poses.

Layout of a fleet YAML (like crazyswarm2's crazyflies.yaml)::

    robots:
      - {id: 0, type: 1, beacon: true, x: -12.5, y: 30.1, yaw: 0.0}

``random_fleet`` draws a seeded deployment in the +/-``half_size`` workspace, outside
the obstacles, with a minimum separation, and spreads the beacons over the swarm.

A fleet's (x, y) is where the operator meant to put each robot, not where it stands:
``place_fleet`` draws the true spawn positions, the configured ones plus a Gaussian
placement error of ``placement_std_m`` per axis. The simulators (headless and sim_node)
spawn the robots there; the agents start from the configured position with that standard
deviation as their prior (a deployment prior with its stated uncertainty) and learn where
they are from their GPS (beacons) or their first trilateration fix.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import dataclasses
from dataclasses import dataclass
import pathlib

import numpy as np
import shapely
from shapely.geometry import Polygon
import yaml

PLACEMENT_STD_M = 0.3   # m per axis: how far a robot stands from its configured position
# Stream key of the placement error: independent of the other draws of the same seed.
_PLACEMENT_STREAM = 0x504C4143


class FleetError(ValueError):
    """A fleet that cannot be deployed or read."""


@dataclass(frozen=True)
class RobotSpec:
    """One robot of the fleet."""

    id: int
    type: int
    is_beacon: bool
    x: float
    y: float
    yaw: float = 0.0


def random_fleet(type_counts: Mapping[int, int], n_beacons: int, rng: np.random.Generator,
                 *, half_size: float = 50.0, obstacles: Sequence[Polygon] = (),
                 min_separation: float = 1.5, margin: float = 1.0) -> list[RobotSpec]:
    """Ids 0..N-1 in type order, random positions, beacons chosen far apart."""
    n = sum(type_counts.values())
    if n <= 0:
        raise FleetError('the fleet needs at least one robot')
    if not 0 <= n_beacons <= n:
        raise FleetError(f'{n_beacons} beacons for {n} robots; use 0..{n}')
    lo, hi = -half_size + margin, half_size - margin
    if hi <= lo:
        raise FleetError(f'workspace half size {half_size} m is too small')
    blocked = shapely.union_all([o.buffer(margin) for o in obstacles]) if obstacles else None
    if blocked is not None:
        shapely.prepare(blocked)
    points: list[np.ndarray] = []
    tries = 0
    while len(points) < n:
        tries += 1
        if tries > 200 * n:
            raise FleetError(f'cannot place {n} robots {min_separation} m apart in the '
                             f'+/-{half_size} m workspace outside the obstacles; enlarge it '
                             'or lower the count')
        p = rng.uniform(lo, hi, size=2)
        if blocked is not None and blocked.contains(shapely.Point(p)):
            continue
        if points and np.min(np.linalg.norm(np.array(points) - p, axis=1)) < min_separation:
            continue
        points.append(p)
    pos = np.array(points)
    # Farthest-point selection spreads the beacons over the deployment.
    beacons: list[int] = []
    if n_beacons:
        beacons.append(int(rng.integers(n)))
        dist = np.linalg.norm(pos - pos[beacons[0]], axis=1)
        while len(beacons) < n_beacons:
            k = int(np.argmax(dist))
            beacons.append(k)
            dist = np.minimum(dist, np.linalg.norm(pos - pos[k], axis=1))
    types = [t for t in sorted(type_counts) for _ in range(type_counts[t])]
    return [RobotSpec(i, types[i], i in beacons, float(pos[i, 0]), float(pos[i, 1]),
                      float(rng.uniform(-np.pi, np.pi))) for i in range(n)]


def save_fleet(path: str | pathlib.Path, robots: Sequence[RobotSpec]) -> None:
    """Write the fleet YAML."""
    data = {'robots': [{'id': r.id, 'type': r.type, 'beacon': r.is_beacon, 'x': r.x,
                        'y': r.y, 'yaw': r.yaw} for r in robots]}
    pathlib.Path(path).write_text(yaml.safe_dump(data, sort_keys=False), encoding='utf-8')


def load_fleet(path: str | pathlib.Path) -> list[RobotSpec]:
    """Read a fleet YAML; FleetError names the bad entry."""
    try:
        data = yaml.safe_load(pathlib.Path(path).read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise FleetError(f'cannot read fleet file {path}: {exc}') from exc
    robots = data.get('robots') if isinstance(data, dict) else None
    if not isinstance(robots, list) or not robots:
        raise FleetError(f'fleet file {path} needs a non-empty "robots" list')
    out = []
    for k, r in enumerate(robots):
        try:
            out.append(RobotSpec(int(r['id']), int(r['type']), bool(r.get('beacon', False)),
                                 float(r['x']), float(r['y']), float(r.get('yaw', 0.0))))
        except (KeyError, TypeError, ValueError):
            raise FleetError(f'fleet file {path} robot {k} needs numeric id, type, x, y') \
                from None
    if len({r.id for r in out}) != len(out):
        raise FleetError(f'fleet file {path} repeats robot ids')
    return out



def place_fleet(fleet: Sequence[RobotSpec], placement_std_m: float, seed: int, *,
                radii: Sequence[float] | None = None, obstacles: Sequence[Polygon] = (),
                half_size: float | None = None, rounds: int = 200) -> list[RobotSpec]:
    """Where the robots really stand: each configured (x, y) plus a placement error.

    The error is N(0, ``placement_std_m``^2) per axis, drawn from its own stream of
    ``seed`` so that headless and sim_node place the same fleet identically. With
    ``radii`` (coverage radius per robot) the error never puts a coverage circle where
    the configured one would not be allowed: overlapping another robot's, an obstacle
    or the +/-``half_size`` workspace edge. The robots in such a conflict draw again,
    for up to ``rounds`` rounds; FleetError when the fleet is too tight for the error.
    """
    if not (np.isfinite(placement_std_m) and placement_std_m >= 0.0):
        raise FleetError(f'placement_std_m must be a finite number >= 0 m, got '
                         f'{placement_std_m}; use e.g. {PLACEMENT_STD_M}')
    if placement_std_m == 0.0 or not fleet:
        return list(fleet)
    if radii is not None and len(radii) != len(fleet):
        raise FleetError(f'{len(radii)} radii for {len(fleet)} robots')
    rng = np.random.default_rng([_PLACEMENT_STREAM, int(seed)])
    configured = np.array([[r.x, r.y] for r in fleet], dtype=float)
    placed = configured + rng.normal(0.0, placement_std_m, configured.shape)
    if radii is not None:
        conflicts = _Conflicts(configured, np.asarray(radii, float), obstacles, half_size)
        for _ in range(rounds):
            bad = conflicts.of(placed)
            if not bad.any():
                break
            placed[bad] = configured[bad] + rng.normal(0.0, placement_std_m,
                                                       (int(bad.sum()), 2))
        else:
            k = int(np.flatnonzero(bad)[0])
            raise FleetError(
                f'robot {fleet[k].id}: no placement error of placement_std_m='
                f'{placement_std_m} m keeps it clear of the others, the obstacles and the '
                f'edge in {rounds} draws; spread the fleet out or lower placement_std_m')
    return [dataclasses.replace(r, x=float(p[0]), y=float(p[1]))
            for r, p in zip(fleet, placed)]


class _Conflicts:
    """Which robots' coverage circles overlap another's, an obstacle or the workspace
    edge where their configured circles do not."""

    def __init__(self, configured: np.ndarray, radii: np.ndarray,
                 obstacles: Sequence[Polygon], half_size: float | None) -> None:
        self.radii = radii
        self.half_size = half_size
        self.blocked = shapely.union_all(list(obstacles)) if obstacles else None
        self.pair_limit = radii[:, None] + radii[None, :]
        self.check_pairs = ~self._overlaps(configured)
        self.check_edge = ~self._outside(configured)
        self.check_obstacles = ~self._blocked(configured)

    def _overlaps(self, xy: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
        overlap = d < self.pair_limit
        np.fill_diagonal(overlap, False)
        return overlap

    def _outside(self, xy: np.ndarray) -> np.ndarray:
        if self.half_size is None:
            return np.zeros(len(xy), dtype=bool)
        return np.max(np.abs(xy), axis=1) > self.half_size - self.radii

    def _blocked(self, xy: np.ndarray) -> np.ndarray:
        if self.blocked is None:
            return np.zeros(len(xy), dtype=bool)
        return shapely.distance(self.blocked, shapely.points(xy)) < self.radii

    def of(self, xy: np.ndarray) -> np.ndarray:
        """Mask of the robots in a conflict at positions ``xy``."""
        pairs = self._overlaps(xy) & self.check_pairs
        return (pairs.any(axis=1) | (self._outside(xy) & self.check_edge)
                | (self._blocked(xy) & self.check_obstacles))
