"""The fleet: one source of truth for robot ids, types, beacons and deployment poses,
for the simulated swarm and the real robots alike.

Layout of a fleet YAML (like crazyswarm2's crazyflies.yaml)::

    robots:
      - {id: 0, type: 1, beacon: true, x: -12.5, y: 30.1, yaw: 0.0}
      - {id: 1, type: 2, x: -0.4, y: -0.8, address: '0013A20041000002', color: blue,
         radius: 0.11}
    cover_colors: {blue: [40, 70, 200]}

A real robot (thesis ch. 5) also carries ``address``, the 64-bit serial number of its
XBee, and the ``color`` and ``radius`` of its cover for the overhead camera; a hardware
fleet (``load_fleet(..., hardware=True)``) needs the address of every robot, and its
``cover_colors`` give each cover colour's RGB. The shipped hardware fleet is
``HARDWARE_FLEET`` (thesis Table 5.1).

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
import math
import pathlib

import numpy as np
import shapely
from shapely.geometry import Polygon
import yaml

from swarm_common.paths import package_file

HARDWARE_FLEET = package_file('swarm_bridge', 'config/fleet.yaml')
PLACEMENT_STD_M = 0.3   # m per axis: how far a robot stands from its configured position
# Stream key of the placement error: independent of the other draws of the same seed.
_PLACEMENT_STREAM = 0x504C4143


class FleetError(ValueError):
    """A fleet that cannot be deployed or read."""


@dataclass(frozen=True)
class RobotSpec:
    """One robot of the fleet: the agent ``id`` that drives it, its type and role, where it
    is deployed (m, rad CCW) and, for a real robot, its radio address and cover."""

    id: int
    type: int
    is_beacon: bool
    x: float
    y: float
    yaw: float = 0.0
    address: int | None = None   # XBee 64-bit serial number (SH + SL)
    color: str = ''              # colour of the cover's circles (thesis 5.1, Fig. 5.2)
    radius: float = 0.1          # radius of the cover, m

    @property
    def address_hex(self) -> str:
        """The radio address as 16 hex digits (SH then SL)."""
        return f'{self.address:016X}' if self.address is not None else ''


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
    """Write the fleet YAML (hardware fields only where set)."""
    rows = []
    for r in robots:
        row = {'id': r.id, 'type': r.type, 'beacon': r.is_beacon, 'x': r.x, 'y': r.y,
               'yaw': r.yaw}
        if r.address is not None:
            row.update(address=r.address_hex, color=r.color, radius=r.radius)
        rows.append(row)
    pathlib.Path(path).write_text(yaml.safe_dump({'robots': rows}, sort_keys=False),
                                  encoding='utf-8')


def parse_address(text: str | int) -> int:
    """Parse a 64-bit XBee address given as 16 hex digits (spaces and 0x allowed)."""
    if isinstance(text, int):
        value = text
    else:
        digits = str(text).replace(' ', '').lower().removeprefix('0x')
        if len(digits) != 16:
            raise FleetError(f'address {text!r} must be 16 hex digits (SH + SL), '
                             f'e.g. 0013A20041000001')
        try:
            value = int(digits, 16)
        except ValueError:
            raise FleetError(f'address {text!r} is not hexadecimal') from None
    if not 0 <= value < 1 << 64:
        raise FleetError(f'address {text!r} does not fit in 64 bits')
    return value


def _read(path: pathlib.Path) -> dict:
    try:
        data = yaml.safe_load(path.read_text(encoding='utf-8'))
    except (OSError, yaml.YAMLError) as exc:
        raise FleetError(f'cannot read fleet file {path}: {exc}') from exc
    return data if isinstance(data, dict) else {}


def _robot(path: pathlib.Path, k: int, r, hardware: bool) -> RobotSpec:
    if not isinstance(r, dict):
        raise FleetError(f'fleet file {path} robot {k} must be a mapping of id, type, x, y')
    if hardware and 'address' not in r:
        raise FleetError(f'fleet file {path} robot {k} needs the address of its XBee '
                         '(16 hex digits, SH + SL)')
    try:
        spec = RobotSpec(int(r['id']), int(r['type']), bool(r.get('beacon', False)),
                         float(r['x']), float(r['y']), float(r.get('yaw', 0.0)),
                         color=str(r.get('color', '')), radius=float(r.get('radius', 0.1)))
    except (KeyError, TypeError, ValueError):
        raise FleetError(f'fleet file {path} robot {k} needs numeric id, type, x, y') \
            from None
    if 'address' in r:
        spec = dataclasses.replace(spec, address=parse_address(r['address']))
    return spec


def load_fleet(path: str | pathlib.Path | None = None, *,
               hardware: bool = False) -> list[RobotSpec]:
    """Read a fleet YAML (``HARDWARE_FLEET`` when ``path`` is None); FleetError names the
    bad entry. ``hardware`` requires every robot's radio address. Ids, and addresses
    where given, are unique."""
    path = pathlib.Path(path) if path else HARDWARE_FLEET
    robots = _read(path).get('robots')
    if not isinstance(robots, list) or not robots:
        raise FleetError(f'fleet file {path} needs a non-empty "robots" list')
    out = [_robot(path, k, r, hardware) for k, r in enumerate(robots)]
    for key in ('id', 'address'):
        values = [getattr(r, key) for r in out if getattr(r, key) is not None]
        dupes = sorted({v for v in values if values.count(v) > 1})
        if dupes:
            raise FleetError(f'fleet file {path} repeats robot {key}s {dupes}; every robot '
                             'needs its own')
    return out


# Never the source address of a received XBee frame (0x90), so never a coordinator's:
# the coordinator alias (a destination only), broadcast, "64-bit address unknown".
NOT_A_SENDER = (0x0000000000000000, 0x000000000000FFFF, 0xFFFFFFFFFFFFFFFF)


def load_coordinator(path: str | pathlib.Path | None = None) -> int:
    """The fleet file's ``coordinator``: the 64-bit address (SH + SL) of the XBee on the
    bridge's serial port, the one sender whose commands the robots obey (the firmware is
    built with it: firmware/PROTOCOL.md). FleetError when it is missing, not quoted hex,
    not a sender's address, or a robot's."""
    path = pathlib.Path(path) if path else HARDWARE_FLEET
    text = _read(path).get('coordinator')
    if not isinstance(text, str):
        raise FleetError(f"fleet file {path} needs coordinator: '<16 hex digits>' (quoted), "
                         "the SH + SL of the bridge's XBee")
    value = parse_address(text)
    if value in NOT_A_SENDER:
        raise FleetError(f'fleet file {path}: coordinator {text} is not an XBee serial '
                         "number; give the bridge's XBee's own SH + SL")
    if value in {r.address for r in load_fleet(path)}:
        raise FleetError(f"fleet file {path}: coordinator {text} is also a robot's address")
    return value


def load_cover_colors(path: str | pathlib.Path | None = None) -> dict[str, tuple[int, int, int]]:
    """The fleet file's ``cover_colors``: colour name -> RGB 0-255 (thesis 5.1, Fig. 5.2).

    Every robot's ``color`` must be listed; a fleet file without the section gets the
    shipped hardware fleet's table for the names it uses.
    """
    path = pathlib.Path(path) if path else HARDWARE_FLEET
    robots = load_fleet(path)
    table = _read(path).get('cover_colors')
    if table is None and path != HARDWARE_FLEET and HARDWARE_FLEET.exists():
        table = _read(HARDWARE_FLEET).get('cover_colors')
    colors = {}
    for name, rgb in (table or {}).items():
        if (not isinstance(rgb, (list, tuple)) or len(rgb) != 3
                or not all(isinstance(v, (int, float)) and 0 <= v <= 255 for v in rgb)):
            raise FleetError(f'{path}: cover_colors {name}: give [r, g, b] with 0-255 values')
        colors[str(name)] = tuple(int(v) for v in rgb)
    unknown = sorted({r.color for r in robots if r.color} - set(colors))
    if unknown:
        raise FleetError(f'{path}: robot colours {unknown} are not in cover_colors; add '
                         'their RGB values there')
    return colors


def initial_poses(flat: Sequence[float], robots: Sequence[RobotSpec]
                  ) -> list[tuple[float, float, float]]:
    """Start poses (x m, y m, yaw rad CCW): the fleet's, unless the flat parameter list
    (x, y, yaw in degrees per robot) overrides them."""
    if len(flat) <= 1:
        return [(r.x, r.y, r.yaw) for r in robots]
    if len(flat) != 3 * len(robots):
        raise FleetError(f'initial_poses holds {len(flat)} numbers; give x,y,yaw_deg for '
                         f'each of the {len(robots)} robots ({3 * len(robots)} numbers)')
    return [(flat[3 * i], flat[3 * i + 1], math.radians(flat[3 * i + 2]))
            for i in range(len(robots))]


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
