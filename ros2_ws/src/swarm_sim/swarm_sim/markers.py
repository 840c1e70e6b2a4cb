"""RViz view of the simulated swarm: one ``visualization_msgs/MarkerArray`` per call.

What sim_node publishes on ``/swarm/markers`` (issue 6), built here from plain data so
it is testable without ROS. Namespaces, all in the ``map`` frame:

``robots``    one flat cylinder per robot, the diameter of its coverage circle (Table
              4.1), coloured by type; removed robots are deleted.
``modes``     a small sphere above each robot, coloured by the mode its agent last
              reported (thesis 3.1.3): green normal, orange lost, red returning home,
              grey not heard yet.
``goals``     a faint disc per goal state, its coverage radius, in its type's colour.
``shape``     the formation contour and its holes (line strips).
``obstacles`` the obstacles as they stand now (after any move), outlined.
``links``     one line per radio link of the medium (line list).

Type colours are those of the figures and the pybullet bodies
(``swarm_common.robot_types.TYPE_COLOURS``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from geometry_msgs.msg import Point
import numpy as np
from shapely.geometry import Polygon
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from swarm_common.robot_types import OTHER_COLOUR
from swarm_sim.live_view import (
    link_pairs,
    mode_colour,
    MODE_COLOURS,
    polygon_rings,
    type_colour,
    UNHEARD,
)

__all__ = ['marker_count', 'MODE_COLOURS', 'swarm_markers', 'UNHEARD']

OTHER = OTHER_COLOUR


def _marker(stamp, ns: str, marker_id: int, kind: int, rgb: Sequence[float],
            alpha: float = 1.0) -> Marker:
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = 'map'
    m.ns, m.id, m.type, m.action = ns, int(marker_id), kind, Marker.ADD
    m.pose.orientation.w = 1.0
    m.color = ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))
    return m


def _ring_points(coords, z: float) -> list[Point]:
    return [Point(x=float(x), y=float(y), z=z) for x, y in coords]


def _outline(stamp, ns: str, first_id: int, polygon: Polygon, rgb, width: float,
             z: float) -> list[Marker]:
    """A closed line strip per ring of ``polygon`` (exterior, then holes)."""
    out = []
    for k, ring in enumerate(polygon_rings(polygon)):
        m = _marker(stamp, ns, first_id + k, Marker.LINE_STRIP, rgb)
        m.scale.x = width
        m.points = _ring_points([*ring, ring[0]], z)
        out.append(m)
    return out


def swarm_markers(stamp, ids: Sequence[int], types: Sequence[int],
                  radii: Sequence[float], positions: np.ndarray, alive: Sequence[bool], *,
                  modes: Mapping[int, int] | None = None, goals: Sequence = (),
                  region: Polygon | None = None, obstacles: Sequence[Polygon] = (),
                  links: np.ndarray | None = None) -> MarkerArray:
    """Every marker of the swarm view (see the module docstring).

    ``positions`` (N, 2) true positions in metres; ``modes`` agent id -> AgentState mode;
    ``goals`` objects with ``id``, ``type``, ``x``, ``y``, ``radius``; ``links`` the
    medium's (N, N) boolean adjacency in the order of ``ids``. Each namespace is cleared
    first (DELETEALL), so goals, links or obstacles that went away disappear too.
    """
    modes = modes or {}
    out = MarkerArray()
    for ns in ('goals', 'shape', 'obstacles', 'links'):
        clear = _marker(stamp, ns, 0, Marker.CUBE, OTHER)
        clear.action = Marker.DELETEALL
        out.markers.append(clear)
    for i, (rid, rtype, radius) in enumerate(zip(ids, types, radii)):
        x, y = float(positions[i, 0]), float(positions[i, 1])
        body = _marker(stamp, 'robots', rid, Marker.CYLINDER, type_colour(rtype), 0.8)
        mode = _marker(stamp, 'modes', rid, Marker.SPHERE, mode_colour(modes.get(int(rid), -1)))
        if not alive[i]:
            body.action = mode.action = Marker.DELETE
        body.pose.position = Point(x=x, y=y, z=0.05)
        body.scale.x = body.scale.y = 2.0 * float(radius)
        body.scale.z = 0.1
        mode.pose.position = Point(x=x, y=y, z=0.35)
        mode.scale.x = mode.scale.y = mode.scale.z = max(0.15, 0.4 * float(radius))
        out.markers += [body, mode]
    for g in goals:
        disc = _marker(stamp, 'goals', g.id, Marker.CYLINDER, type_colour(g.type), 0.25)
        disc.pose.position = Point(x=float(g.x), y=float(g.y), z=0.01)
        disc.scale.x = disc.scale.y = 2.0 * float(g.radius)
        disc.scale.z = 0.02
        out.markers.append(disc)
    if region is not None:
        out.markers += _outline(stamp, 'shape', 0, region, (0.1, 0.1, 0.1), 0.08, 0.02)
    first = 0
    for polygon in obstacles:
        rings = _outline(stamp, 'obstacles', first, polygon, (0.35, 0.25, 0.15), 0.12, 0.5)
        out.markers += rings
        first += len(rings)
    if links is not None and len(ids):
        pairs = link_pairs(links, alive)
        if pairs:
            lines = _marker(stamp, 'links', 0, Marker.LINE_LIST, (0.3, 0.3, 0.9), 0.35)
            lines.scale.x = 0.03
            z = 0.2
            for pair in pairs:
                for i in pair:
                    lines.points.append(Point(x=float(positions[i, 0]),
                                              y=float(positions[i, 1]), z=z))
            out.markers.append(lines)
    return out


def marker_count(array: MarkerArray, ns: str) -> int:
    """Markers of one namespace that add or modify something (tests, debugging)."""
    return sum(1 for m in array.markers if m.ns == ns and m.action == Marker.ADD)

