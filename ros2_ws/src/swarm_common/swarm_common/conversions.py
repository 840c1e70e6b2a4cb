"""Pure conversions between swarm_msgs shape/goal messages and the mission's domain types.

Imports message classes only (no rclpy). ``shape_from_msg`` validates through
``shape_from_rings``, so a malformed shape message raises ``ShapeError`` with a
message naming the problem.
"""

from __future__ import annotations

from collections.abc import Iterable

from builtin_interfaces.msg import Time
import numpy as np

from swarm_common.goals import Goal
from swarm_common.shapes import Shape, shape_from_rings
from swarm_msgs.msg import FormationShape, GoalArray, GoalState, Ring


def _ring_to_msg(coords: np.ndarray) -> Ring:
    coords = np.asarray(coords, dtype=float)
    if len(coords) > 1 and np.allclose(coords[0], coords[-1]):
        coords = coords[:-1]
    ring = Ring()
    ring.x = [float(v) for v in coords[:, 0]]
    ring.y = [float(v) for v in coords[:, 1]]
    return ring


def _ring_from_msg(ring: Ring) -> np.ndarray:
    return np.column_stack([np.asarray(ring.x, dtype=float), np.asarray(ring.y, dtype=float)]) \
        if len(ring.x) == len(ring.y) else np.zeros((0, 2))


def shape_to_msg(shape: Shape, version: int, stamp: Time | None = None,
                 frame_id: str = 'map') -> FormationShape:
    """Shape -> swarm_msgs/FormationShape."""
    msg = FormationShape()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.version = int(version)
    msg.name = shape.name
    msg.outer = _ring_to_msg(np.asarray(shape.region.exterior.coords))
    msg.holes = [_ring_to_msg(np.asarray(h.coords)) for h in shape.region.interiors]
    msg.obstacles = [_ring_to_msg(np.asarray(o.exterior.coords)) for o in shape.obstacles]
    return msg


def shape_from_msg(msg: FormationShape) -> Shape:
    """swarm_msgs/FormationShape -> validated Shape (raises ShapeError when malformed)."""
    return shape_from_rings(
        _ring_from_msg(msg.outer),
        holes=[_ring_from_msg(h) for h in msg.holes],
        obstacles=[_ring_from_msg(o) for o in msg.obstacles],
        name=msg.name or 'shape')


def goals_to_msg(goals: Iterable[Goal], version: int, shape_version: int, method: str,
                 stamp: Time | None = None, frame_id: str = 'map') -> GoalArray:
    """Goals -> swarm_msgs/GoalArray."""
    msg = GoalArray()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.version = int(version)
    msg.shape_version = int(shape_version)
    msg.method = method
    for g in goals:
        msg.goals.append(GoalState(id=int(g.id), type=int(g.type), x=float(g.x), y=float(g.y),
                                   radius=float(g.radius), beacon=bool(g.beacon)))
    return msg


def goals_from_msg(msg: GoalArray) -> list[Goal]:
    """swarm_msgs/GoalArray -> goals (non-finite entries dropped)."""
    return [Goal(id=int(g.id), type=int(g.type), x=float(g.x), y=float(g.y),
                 radius=float(g.radius), beacon=bool(g.beacon))
            for g in msg.goals if np.isfinite([g.x, g.y, g.radius]).all()]
