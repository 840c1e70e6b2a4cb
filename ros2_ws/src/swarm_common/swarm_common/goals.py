"""Typed goal states g_i in G produced by shape partitioning (thesis 3.2.2.1).

A goal is the centre of one agent's coverage circle inside the formation shape: the
robot type that must occupy it and that type's coverage radius (Table 4.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np


class PartitionError(ValueError):
    """A shape that cannot be partitioned for the swarm (e.g. too small: says by how much).

    Defined here so that every partitioning method can raise it; re-exported by
    :mod:`swarm_mission.partition`.
    """


@dataclass(frozen=True)
class Goal:
    """One goal state: id, robot type, centre (m, map frame) and coverage radius (m).

    ``beacon``: a goal for a position beacon of that type only, chosen so that every
    goal has beacons to trilaterate against (``swarm_mission.beacon_goals``).
    """

    id: int
    type: int
    x: float
    y: float
    radius: float
    beacon: bool = False


def goal_positions(goals: Sequence[Goal]) -> np.ndarray:
    """Centres of ``goals`` as an (n, 2) array."""
    return np.array([[g.x, g.y] for g in goals], dtype=float).reshape(-1, 2)


def goal_radii(goals: Sequence[Goal]) -> np.ndarray:
    """Coverage radii of ``goals`` as an (n,) array."""
    return np.array([g.radius for g in goals], dtype=float)


@dataclass(frozen=True)
class TypeGoals:
    """The goals of one robot type in id order, with the arrays an agent's cost rows and
    assignment read at every consensus round (built once per goal list)."""

    goals: tuple[Goal, ...]
    positions: np.ndarray     # (n, 2) centres
    beacon: np.ndarray        # (n,) bool: beacon goals
    ids: tuple[int, ...]
    types: np.ndarray         # (n,) int: their type, every one alike

    @classmethod
    def of(cls, goals: Sequence[Goal], agent_type: int) -> TypeGoals:
        mine = tuple(sorted((g for g in goals if g.type == agent_type), key=lambda g: g.id))
        return cls(mine, goal_positions(mine), np.array([g.beacon for g in mine], dtype=bool),
                   tuple(g.id for g in mine), np.array([g.type for g in mine], dtype=int))


def goals_to_json(goals: Sequence[Goal]) -> dict:
    """The ``goals.json`` document: ``{"goals": [{"x", "y", "type", "radius", "id",
    "beacon"}, ...]}``."""
    return {'goals': [asdict(g) for g in goals]}


HEX_PACKING_DENSITY = np.pi / (2 * np.sqrt(3))   # densest packing of equal disks (0.9069)


def placement_violations(points: np.ndarray, radii: np.ndarray, region,
                         tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Which coverage circles leave ``region`` and which pairs overlap.

    Returns (indices of circles not wholly inside the region, (k, 2) overlapping index
    pairs). Used by the partitioners as their final guarantee and by the tests.
    """
    from scipy.spatial import cKDTree
    import shapely
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    radii = np.asarray(radii, dtype=float)
    inside = shapely.contains_xy(region, pts[:, 0], pts[:, 1])
    clearance = shapely.distance(region.boundary, shapely.points(pts))
    outside = np.flatnonzero(~inside | (clearance < radii - tol))
    if len(pts) < 2:
        return outside, np.zeros((0, 2), dtype=int)
    pairs = cKDTree(pts).query_pairs(2 * radii.max(), output_type='ndarray')
    if len(pairs):
        dist = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
        pairs = pairs[dist < radii[pairs[:, 0]] + radii[pairs[:, 1]] - tol]
    return outside, pairs.reshape(-1, 2)


def required_area(radii: np.ndarray) -> float:
    """Smallest area that could hold these coverage circles (hexagonal packing bound)."""
    return float(np.pi * np.sum(np.square(radii)) / HEX_PACKING_DENSITY)


def check_fits(area: float, radii: np.ndarray) -> float:
    """The area the circles need; PartitionError when they cannot fit in ``area`` m^2.

    The message says by how much the shape must be scaled (every partitioner's check).
    """
    need = required_area(radii)
    if need > area:
        raise PartitionError(
            f'the {len(radii)} coverage circles need at least {need:.3g} m^2 but the shape '
            f'has {area:.3g} m^2: scale the shape by at least {np.sqrt(need / area):.3g}')
    return need
