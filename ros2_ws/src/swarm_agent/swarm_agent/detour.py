"""Going round the robots that hold one still far from its goal (beyond the thesis).

The cost rows and paths of 3.2.2.2 plan round the shape's obstacles only, and the
collision filter (``setpoint.avoid_collisions``) is a local rule. On the arena, where
goals leave less room between the covers of neighbouring robots than a robot needs, a
robot crossing the formation can be pressed into a pocket between two robots at or near
their goals, every safe direction pointing away from its own goal: in a hardware-in-
the-loop run of hw_square whose camera stalled for 10 s at the start, robot 2 (11 cm)
set off 8 s after robot 0 (16 cm) had taken the centre, went round it on the north side
and stood for the last 50 s of the run between robots 0 and 3, 0.45 m from its goal, the
gap between their covers 19 cm. Giving way (``setpoint.GiveWay``) is for robots near
their goals and opens a few centimetres, not the 3 cm this robot lacked plus its path
round.

:class:`Detour` therefore plans that robot's way round: held (``setpoint.HeldClock``) for
``detour_after_s`` two radii or more from its goal, it follows the shortest path
(visibility graph and Dijkstra, ``costs.VisibilityGraph``, as its cost rows) among the
shape's grown obstacles and the discs of its neighbours, each grown by its own cover
(``free_space.grow_discs``: radius r_i + r_j), planned again at every outer tick from
where the neighbours are then. It ends when nothing of that kind stands between the
robot and its goal any more (the path has no corner left), so the ordinary path and
filter take over; a goal that a neighbour's disc covers has no such path and also ends
it. Off (``detour_after_s`` 0) in the simulation, whose 0.3 m buffer and 0.5 m/s leave
room for the filter's swerve.

Pure module (no rclpy).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from shapely.geometry import Polygon

from swarm_agent.costs import VisibilityGraph
from swarm_agent.free_space import grow_discs, merge
from swarm_agent.setpoint import GiveWay, HeldClock, SetpointParams


class Detour:
    """Whether a robot held far from its goal goes round its neighbours, and the path."""

    def __init__(self, params: SetpointParams, radius: float) -> None:
        self.params = params
        self.radius = float(radius)
        self.far_m = GiveWay.NEAR_GOAL_RADII * self.radius    # nearer, it gives way
        self._held = HeldClock()
        self.active = False
        self.count = 0                      # detours so far

    def observe(self, t: float, setpoint, command, to_goal: float) -> None:
        """The command the filter gave at ``t`` for ``setpoint`` (m/s each), the robot
        ``to_goal`` m from its goal (inf: none, e.g. returning home)."""
        if self.params.detour_after_s <= 0.0 or self.active:
            self._held.reset()
        elif self._held.held_for(t, setpoint, command, self.params.detour_after_s,
                                 to_goal >= self.far_m):
            self.active = True
            self.count += 1

    def waypoints(self, position, target, offsets, radii,
                  obstacles: Sequence[Polygon]) -> np.ndarray | None:
        """While a detour is on: the waypoints from ``position`` to ``target`` round the
        neighbours at ``offsets`` (k, 2, from this robot, m) of covers ``radii`` (k,) and
        the shape's ``obstacles`` (grown by this robot's cover); None when it is off or
        has just ended (the caller plans as usual)."""
        if not self.active:
            return None
        position = np.asarray(position, dtype=float).reshape(2)
        offsets = np.asarray(offsets, dtype=float).reshape(-1, 2)
        discs = grow_discs(position + offsets, np.asarray(radii, dtype=float) + self.radius)
        graph = VisibilityGraph(merge(list(obstacles) + discs))
        start, escape = graph.escape(position)    # out of a disc it touches, if in one
        path = graph.path(start, target)
        if len(path) <= 2:     # [start, target]: nothing in the way, or no way round
            self.active = False
            return None
        return np.vstack([position, path]) if escape > 0.0 else path
