"""Goal costs: visibility graph and Dijkstra shortest paths (thesis 3.2.2.2, Algs. 3-5).

Each agent type has its own graph over the vertices of the grown obstacles (its
forbidden space, ``free_space.grow_obstacles``). The thesis inserts every goal into
the graph (``S* = S u {g_i}``); we get the same shortest paths more cheaply: one
Dijkstra run from the agent over the obstacle vertices (scipy.sparse.csgraph), then
each goal is reached either straight from the agent or from the best vertex that sees
it. Visibility tests are vectorised shapely predicates against the obstacles shrunk by
a hair, so paths may slide along an obstacle's edge but never cut through it.

A start inside a grown obstacle (the agent's disc overlaps an obstacle, or its position
estimate is off by metres) would see nothing and report every goal unreachable. Instead
the agent first leaves its forbidden space the shortest way, to the nearest boundary
point of that grown obstacle: costs include that escape distance and ``path`` starts
with it. A goal inside a grown obstacle, or in a region no free path reaches, costs inf.

``class_costs`` keeps beacons on beacon goals: a goal of the other class (a beacon goal
for a robot without GPS, another goal for a beacon) costs inf in the agent's row, so the
Hungarian assignment per type pairs beacons with beacon goals unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
import shapely
from shapely.geometry import Polygon
import shapely.ops

EPS = 1e-6


class VisibilityGraph:
    """Shortest collision-free paths among grown obstacles for one agent type."""

    def __init__(self, grown_obstacles: Sequence[Polygon],
                 workspace: Polygon | None = None) -> None:
        self.obstacles = [o for o in grown_obstacles if not o.is_empty]
        self.workspace = workspace
        if self.obstacles:
            blocker = shapely.union_all([o.buffer(-EPS) for o in self.obstacles])
            shapely.prepare(blocker)
            self._blocker = blocker
            verts = []
            for o in self.obstacles:
                verts.extend(np.asarray(o.exterior.coords)[:-1])
                for hole in o.interiors:
                    verts.extend(np.asarray(hole.coords)[:-1])
            self.vertices = np.array(verts, dtype=float).reshape(-1, 2)
            n = len(self.vertices)
            i, j = np.triu_indices(n, k=1)
            visible = self._visible(self.vertices[i], self.vertices[j])
            d = np.linalg.norm(self.vertices[i] - self.vertices[j], axis=1)
            self._vv = csr_matrix((np.r_[d[visible], d[visible]],
                                   (np.r_[i[visible], j[visible]],
                                    np.r_[j[visible], i[visible]])), shape=(n, n))
        else:
            self._blocker = None
            self.vertices = np.zeros((0, 2))
            self._vv = None
        self._goal_cache: tuple[bytes, np.ndarray] | None = None

    # -- visibility
    def _visible(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Vectorised: does the segment a[k]-b[k] avoid every obstacle interior?"""
        a = np.atleast_2d(a)
        b = np.atleast_2d(b)
        if self._blocker is None or len(a) == 0:
            return np.ones(len(a), dtype=bool)
        lines = shapely.linestrings(np.stack([a, b], axis=1))
        same = np.all(np.abs(a - b) < 1e-12, axis=1)
        blocked = shapely.intersects(self._blocker, lines)
        blocked[same] = shapely.intersects(self._blocker, shapely.points(a[same]))
        return ~blocked

    def _goal_vertex(self, goals: np.ndarray) -> np.ndarray:
        """(G, V) distances from each goal to each vertex it sees (inf if hidden), cached."""
        key = goals.tobytes()
        if self._goal_cache is not None and self._goal_cache[0] == key:
            return self._goal_cache[1]
        g, v = len(goals), len(self.vertices)
        gi, vi = np.repeat(np.arange(g), v), np.tile(np.arange(v), g)
        vis = self._visible(goals[gi], self.vertices[vi]).reshape(g, v)
        dist = np.linalg.norm(goals[:, None, :] - self.vertices[None, :, :], axis=2)
        table = np.where(vis, dist, np.inf)
        self._goal_cache = (key, table)
        return table

    def _from_start(self, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Dijkstra from ``start`` over the vertices: (distances, predecessors)."""
        v = len(self.vertices)
        sv_vis = self._visible(np.repeat(start[None], v, axis=0), self.vertices)
        sv = np.where(sv_vis, np.linalg.norm(self.vertices - start, axis=1), np.inf)
        if v == 0:
            return np.zeros(0), np.zeros(0, dtype=int)
        # Node v (last) is the start; edges start -> visible vertices.
        rows = np.flatnonzero(np.isfinite(sv))
        start_edges = csr_matrix((sv[rows], (np.full(len(rows), v), rows)), shape=(v + 1, v + 1))
        graph = self._vv.copy()
        graph.resize((v + 1, v + 1))
        graph = graph + start_edges
        dist, pred = dijkstra(graph, directed=False, indices=v, return_predecessors=True)
        return dist[:v], pred[:v]

    # -- public API
    def escape(self, point) -> tuple[np.ndarray, float]:
        """The nearest free point to ``point`` and the distance to it (0 if already free).

        Inside a grown obstacle that is the nearest point of its boundary (exterior or a
        hole's), which the visibility tests treat as free.
        """
        point = np.asarray(point, dtype=float).reshape(2)
        if self._blocker is None:
            return point, 0.0
        p = shapely.Point(point[0], point[1])
        if not self._blocker.contains(p):
            return point, 0.0
        for obstacle in self.obstacles:
            if obstacle.contains(p):
                exit_point = shapely.ops.nearest_points(obstacle.boundary, p)[0]
                out = np.array([exit_point.x, exit_point.y])
                return out, float(np.hypot(*(out - point)))
        return point, 0.0

    def cost_row(self, start, goals) -> np.ndarray:
        """Shortest path lengths (m) from ``start`` to every goal; inf when unreachable."""
        start, escape = self.escape(start)
        goals = np.asarray(goals, dtype=float).reshape(-1, 2)
        direct = np.linalg.norm(goals - start, axis=1)
        if self._blocker is None or len(goals) == 0:
            return direct + escape
        straight = self._visible(np.repeat(start[None], len(goals), axis=0), goals)
        cost = np.where(straight, direct, np.inf)
        if (~straight).any() and len(self.vertices):
            dist, _ = self._from_start(start)
            via = (dist[None, :] + self._goal_vertex(goals)).min(axis=1)
            cost = np.where(straight, direct, via)
        return cost + escape

    def cost_matrix(self, starts, goals) -> np.ndarray:
        """(A, G) cost rows for several starts."""
        starts = np.asarray(starts, dtype=float).reshape(-1, 2)
        return np.array([self.cost_row(s, goals) for s in starts]).reshape(len(starts), -1)

    def path(self, start, goal) -> np.ndarray:
        """Waypoints (k, 2) from start to goal, both included; straight line if visible.

        A start inside a grown obstacle first goes to ``escape(start)``; an unreachable
        goal gives the straight line (its cost is inf, so it is never assigned).
        """
        origin = np.asarray(start, dtype=float).reshape(2)
        start, escape = self.escape(origin)
        goal = np.asarray(goal, dtype=float).reshape(2)
        if escape > 0.0:
            return np.vstack([origin, self.path(start, goal)])
        if self._blocker is None or self._visible(start, goal)[0] or not len(self.vertices):
            return np.array([start, goal])
        dist, pred = self._from_start(start)
        to_goal = dist + self._goal_vertex(goal[None])[0]
        best = int(np.argmin(to_goal))
        if not np.isfinite(to_goal[best]):
            return np.array([start, goal])
        chain = [best]
        v = len(self.vertices)
        while pred[chain[-1]] not in (v, -9999) and pred[chain[-1]] >= 0:
            chain.append(int(pred[chain[-1]]))
        return np.vstack([start, self.vertices[chain[::-1]], goal])


def class_costs(costs: np.ndarray, goal_beacon: np.ndarray, is_beacon: bool) -> np.ndarray:
    """``costs`` with the goals of the other class set to inf.

    ``goal_beacon``: per goal, whether it is a beacon goal. When none is (the mission
    does not know the beacons), the row is returned as it is.
    """
    costs = np.asarray(costs, dtype=float)
    goal_beacon = np.asarray(goal_beacon, dtype=bool)
    if not goal_beacon.any():
        return costs
    return np.where(goal_beacon == bool(is_beacon), costs, np.inf)
