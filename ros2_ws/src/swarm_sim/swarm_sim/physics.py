"""The physics behind the world model: the declared backend interface and its two makers.

``PhysicsBackend`` is what ``swarm_sim.world_model.World`` asks of a physics engine:
planar forces in, planar states out, and the two faults that touch bodies (a robot
removed, an obstacle moved). Two backends implement it:

- ``swarm_sim.world.PybulletBackend``: rigid bodies on rough terrain, the thesis's
  Gazebo world of section 4.1 (sim_node's default when pybullet is installed);
- ``PointMassBackend``: the point masses of ``swarm_agent.dynamics`` with Table 4.1's
  friction (the headless evaluator's, and sim_node's without pybullet). Point masses
  have no bodies: a removed robot stays where it stopped (the world no longer pushes
  it), moving an obstacle moves only its radio shadow, and no body contacts are counted.

The spawn checks of a rigid-body world (``check_world``) live here too, so that a bad
fleet is refused with one line naming the robot before any engine is started.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import math
from typing import Protocol, runtime_checkable

import numpy as np
import shapely
from shapely.geometry import Point, Polygon

from swarm_common.robot_types import robot_type, RobotType, RobotTypeError


@runtime_checkable
class PhysicsBackend(Protocol):
    """A physics engine of N robots (fleet indices 0..N-1), planar, map frame."""

    name: str

    @property
    def body_contacts(self) -> int | None:
        """Robot pairs whose bodies began to touch so far (None: no bodies)."""

    def step(self, dt: float, forces: np.ndarray) -> None:
        """Advance by ``dt`` seconds under planar forces (N, 2) in newtons."""

    def positions(self) -> np.ndarray:
        """Planar positions (N, 2) in metres."""

    def velocities(self) -> np.ndarray:
        """Planar velocities (N, 2) in m/s."""

    def yaws(self) -> np.ndarray:
        """Headings (N,) in radians about the world z axis."""

    def count_body_contacts(self, pairs: Iterable[tuple[int, int]]) -> int | None:
        """Of the index pairs whose coverage circles overlap, how many bodies touch."""

    def remove(self, i: int) -> None:
        """Robot ``i`` leaves the world (a fault); idempotent."""

    def move_obstacle(self, k: int, dx: float, dy: float) -> None:
        """Translate obstacle ``k`` of the shape spec by (dx, dy) metres."""

    def close(self) -> None:
        """Release the engine; idempotent."""


class PointMassBackend:
    """``swarm_agent.dynamics.PointMassSwarm`` behind ``PhysicsBackend``."""

    name = 'pointmass'
    body_contacts = None

    def __init__(self, fleet, types: dict[int, RobotType], **_) -> None:
        from swarm_agent.dynamics import PointMassSwarm
        self.model = PointMassSwarm([types[r.type] for r in fleet],
                                    [[r.x, r.y] for r in fleet])

    def step(self, dt: float, forces: np.ndarray) -> None:
        self.model.step(dt, forces)

    def positions(self) -> np.ndarray:
        return self.model.positions

    def velocities(self) -> np.ndarray:
        return self.model.velocities

    def accelerations(self) -> np.ndarray:
        return self.model.accelerations()

    def yaws(self) -> np.ndarray:
        return np.zeros(len(self.model.positions))

    def count_body_contacts(self, pairs: Iterable[tuple[int, int]]) -> None:
        return None

    def remove(self, i: int) -> None:
        """Nothing to take away: the world stops pushing the point (it stays put)."""

    def move_obstacle(self, k: int, dx: float, dy: float) -> None:
        """No bodies to move: the world moves the obstacle's radio shadow."""

    def close(self) -> None:
        pass


def make_backend(name: str, fleet, types: dict[int, RobotType],
                 obstacles: Sequence[Polygon] = (), half_size: float = 50.0,
                 terrain: str = 'rough', seed: int = 0, gui: bool = False,
                 physics_hz: float = 100.0) -> PhysicsBackend:
    """The physics backend by name: pybullet, pointmass, or auto (pybullet if installed)."""
    if name not in ('pybullet', 'pointmass', 'auto'):
        raise ValueError(f'unknown physics backend {name!r}; use pybullet, pointmass or auto')
    if name in ('pybullet', 'auto'):
        try:
            from swarm_sim.world import PybulletBackend
        except ImportError:
            if name == 'pybullet':
                raise
        else:
            return PybulletBackend(fleet, types, obstacles=obstacles, half_size=half_size,
                                   terrain=terrain, seed=seed, gui=gui,
                                   physics_hz=physics_hz)
    return PointMassBackend(fleet, types)


class WorldError(ValueError):
    """A world that cannot be built: bad terrain, obstacles or robot placement."""


def check_world(fleet, types: dict[int, RobotType], obstacles: Sequence[Polygon],
                half_size: float, physics_hz: float, max_force: float,
                terrain: str) -> tuple[list[RobotType], list[Polygon]]:
    """(robot types in fleet order, obstacles) of a buildable world, else ``WorldError``
    naming the parameter, robot or obstacle and the fix."""
    if not (math.isfinite(half_size) and half_size > 0):
        raise WorldError(f'half_size must be a positive number of metres, got {half_size!r}')
    if not (math.isfinite(physics_hz) and 10.0 <= physics_hz <= 10000.0):
        raise WorldError(f'physics_hz must be within 10..10000 Hz, got {physics_hz!r}')
    if not (math.isfinite(max_force) and max_force > 0):
        raise WorldError(f'max_force must be positive, got {max_force!r}')
    if terrain not in ('rough', 'flat'):
        raise WorldError(f'unknown terrain {terrain!r}; use rough or flat')
    if not fleet:
        raise WorldError('the fleet is empty; give at least one robot')
    rtypes = []
    for r in fleet:
        try:
            rtypes.append(robot_type(types, r.type))
        except RobotTypeError as exc:
            raise WorldError(f'robot {r.id}: {exc}') from None
        if not (math.isfinite(r.x) and math.isfinite(r.y) and math.isfinite(r.yaw)):
            raise WorldError(f'robot {r.id}: spawn pose ({r.x}, {r.y}, {r.yaw}) is not finite')
    polygons = []
    for k, o in enumerate(obstacles):
        if not isinstance(o, Polygon) or o.is_empty or not o.is_valid:
            raise WorldError(f'obstacle {k} must be a valid, non-empty shapely Polygon, '
                             f'got {type(o).__name__}')
        polygons.append(o)
    _check_spawns(fleet, rtypes, polygons, half_size)
    return rtypes, polygons


def _check_spawns(fleet, rtypes: list[RobotType], obstacles: list[Polygon],
                  lim: float) -> None:
    xy = np.array([[r.x, r.y] for r in fleet])
    rc = np.array([t.coverage_radius for t in rtypes])
    for r, t in zip(fleet, rtypes):
        room = lim - t.coverage_radius
        if abs(r.x) > room or abs(r.y) > room:
            raise WorldError(
                f'robot {r.id} (type {t.type_id}) at ({r.x:.2f}, {r.y:.2f}) is outside the '
                f'workspace: its coverage circle of {t.coverage_radius} m must lie within '
                f'+/-{lim} m, so |x|, |y| <= {room:.2f} m')
    if obstacles:
        blocked = shapely.union_all(obstacles)
        for r, t in zip(fleet, rtypes):
            gap = blocked.distance(Point(r.x, r.y))
            if gap < t.coverage_radius:
                where = 'inside' if gap == 0 else 'overlapping'
                raise WorldError(
                    f'robot {r.id} (type {t.type_id}) at ({r.x:.2f}, {r.y:.2f}) is {where} '
                    f'an obstacle: move it at least {t.coverage_radius - gap:.2f} m away')
    if len(xy) > 1:
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
        overlap = d < rc[:, None] + rc[None, :]
        np.fill_diagonal(overlap, False)
        if overlap.any():
            i, j = np.argwhere(overlap)[0]
            a, b = fleet[i], fleet[j]
            raise WorldError(
                f'robots {a.id} and {b.id} overlap: their centres are {d[i, j]:.2f} m apart, '
                f'less than the sum of their coverage radii {rc[i] + rc[j]:.2f} m')
