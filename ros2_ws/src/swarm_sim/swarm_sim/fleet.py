"""The fleet: one source of truth for robot ids, types, beacons and initial poses.

Layout of a fleet YAML (like crazyswarm2's crazyflies.yaml)::

    robots:
      - {id: 0, type: 1, beacon: true, x: -12.5, y: 30.1, yaw: 0.0}

``random_fleet`` draws a seeded deployment in the +/-``half_size`` workspace, outside
the obstacles, with a minimum separation, and spreads the beacons over the swarm.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import pathlib

import numpy as np
import shapely
from shapely.geometry import Polygon
import yaml


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
