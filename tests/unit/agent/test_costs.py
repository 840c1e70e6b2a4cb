"""Free space and visibility-graph goal costs (thesis 3.2.2.2, eqs. 3.102-3.103, Algs. 3-5).

The forbidden space of an agent is every obstacle grown by its coverage disc (the
Minkowski sum of eq. 3.103); the goal cost is the length of the shortest path in the
visibility graph of the grown obstacles (Algs. 3-5). Numbers come from geometry: the
area of a square grown by a disc, tangent-and-arc lengths around a grown square.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely import affinity
from shapely.geometry import box, LineString, Point, Polygon

from swarm_agent.costs import VisibilityGraph
from swarm_agent.free_space import check_free, free_space, FreeSpaceError, grow_obstacles
from swarm_common.robot_types import load_robot_types

RADII = sorted(t.coverage_radius for t in load_robot_types().values())  # Table 4.1
SIDE = 2.0
SQUARE = box(-SIDE / 2, -SIDE / 2, SIDE / 2, SIDE / 2)
ERODE = 1e-5  # m: a path may slide along a grown obstacle's edge, never enter it


def minkowski_square_area(side: float, r: float) -> float:
    """Area of a square of ``side`` grown by a disc of radius r: s^2 + 4 s r + pi r^2."""
    return side ** 2 + 4 * side * r + math.pi * r ** 2


def path_length(points: np.ndarray) -> float:
    """Sum of the segment lengths of a polyline."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def around_square_length(start_x: float, half: float, r: float) -> float:
    """Shortest path from (-x, 0) to (x, 0) around the square [-h, h]^2 grown by r.

    Tangent from the start to the corner disc at (-h, h), the arc over that corner to the
    top edge, the top edge of length 2h, and the mirror image on the right.
    """
    dx, dy = -start_x + half, -half        # start minus corner centre
    d = math.hypot(dx, dy)
    tangent = math.sqrt(d * d - r * r)
    phi = math.atan2(dy, dx) % (2 * math.pi)           # direction corner -> start
    touch = phi - math.acos(r / d)                     # upper tangent point's direction
    arc = r * (touch - math.pi / 2) if r > 0 else 0.0  # from there up to the top edge
    return 2 * (tangent + arc) + 2 * half


def random_obstacles(rng: np.random.Generator, count: int) -> list[Polygon]:
    """Disjoint rotated rectangles and triangles in [-20, 20]^2."""
    shapes: list[Polygon] = []
    while len(shapes) < count:
        cx, cy = rng.uniform(-16, 16, 2)
        if rng.random() < 0.5:
            w, h = rng.uniform(0.5, 4.0, 2)
            poly = box(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
        else:
            poly = Polygon(np.array([cx, cy]) + rng.uniform(-2.5, 2.5, (3, 2))).convex_hull
        poly = affinity.rotate(poly, float(rng.uniform(0, 180)), origin='centroid')
        if poly.area > 0.2 and all(poly.distance(s) > 0.2 for s in shapes):
            shapes.append(poly)
    return shapes


def free_points(rng: np.random.Generator, grown: list[Polygon], count: int) -> np.ndarray:
    """Uniform points of [-20, 20]^2 outside every grown obstacle."""
    blocked = shapely.union_all(grown)
    pts = []
    while len(pts) < count:
        p = rng.uniform(-20, 20, 2)
        if not blocked.intersects(Point(p)):
            pts.append(p)
    return np.array(pts)


def assert_path_clear(path: np.ndarray, grown: list[Polygon]) -> None:
    """Every segment of ``path`` avoids the interior of every grown obstacle."""
    eroded = [g.buffer(-ERODE) for g in grown]
    for a, b in zip(path[:-1], path[1:]):
        seg = LineString([a, b])
        for k, g in enumerate(eroded):
            assert not seg.intersects(g), f'segment {a} -> {b} cuts grown obstacle {k}'


# -- free space (eqs. 3.102-3.103)

@pytest.mark.parametrize('r', RADII)
def test_grown_square_area_is_the_minkowski_sum(r):
    exact = minkowski_square_area(SIDE, r)
    fine = grow_obstacles([SQUARE], r, quad_segs=64)
    assert len(fine) == 1
    assert fine[0].area == pytest.approx(exact, rel=2e-4)
    # The default few-vertex polygon circumscribes the exact sum: never smaller, and
    # inside the disc sum of the circumscribed radius R = r / cos(pi / 8).
    coarse = grow_obstacles([SQUARE], r)[0]
    big_r = r / math.cos(math.pi / 8)
    assert exact < coarse.area <= minkowski_square_area(SIDE, big_r)
    # Every point at distance exactly r from the square (the exact sum's boundary).
    angles = np.linspace(0, 2 * np.pi, 721)
    rim = [(SIDE / 2 * np.sign(np.cos(a)) + r * np.cos(a),
            SIDE / 2 * np.sign(np.sin(a)) + r * np.sin(a)) for a in angles]
    rim += [(x, SIDE / 2 + r) for x in np.linspace(-SIDE / 2, SIDE / 2, 21)]
    touching = coarse.buffer(1e-9)       # the polygon's edges are tangent to the rim
    assert all(touching.covers(Point(p)) for p in rim)


def test_overlapping_grown_obstacles_merge_and_free_space_subtracts_them():
    a, b = box(0, 0, 1, 1), box(1.2, 0, 2.2, 1)       # 0.2 m apart
    assert len(grow_obstacles([a, b], 0.05)) == 2      # gap 0.2 > 2 * 0.05 * 1.08
    merged = grow_obstacles([a, b], 0.15)
    assert len(merged) == 1
    workspace = box(-10, -10, 10, 10)
    r = 0.3
    space = free_space(workspace, [SQUARE], r)
    grown = grow_obstacles([SQUARE], r)[0]
    assert space.area == pytest.approx((20 - 2 * r) ** 2 - grown.area, rel=1e-12)


def test_bad_radius_and_point_in_forbidden_space_raise_clear_errors():
    with pytest.raises(FreeSpaceError, match='coverage radius'):
        grow_obstacles([SQUARE], -0.1)
    grown = grow_obstacles([SQUARE], 0.5)
    with pytest.raises(FreeSpaceError, match=r'goal \(1\.20, 0\.00\).*at least 0\.34 m'):
        check_free((1.2, 0.0), grown, 'goal')
    check_free((3.0, 0.0), grown, 'goal')


# -- visibility graph and Dijkstra (Algs. 3-5)

def test_cost_is_the_straight_distance_in_free_space():
    rng = np.random.default_rng(5)
    starts, goals = rng.uniform(-20, 20, (2, 30, 2))
    empty = VisibilityGraph([])
    np.testing.assert_allclose(empty.cost_matrix(starts, goals),
                               np.linalg.norm(starts[:, None] - goals[None], axis=2))
    # With an obstacle off to the side, every segment that misses it stays straight.
    side = VisibilityGraph(grow_obstacles([box(30, 30, 31, 31)], 0.5))
    np.testing.assert_allclose(side.cost_row(starts[0], goals),
                               np.linalg.norm(goals - starts[0], axis=1))
    assert len(side.path(starts[0], goals[0])) == 2


@pytest.mark.parametrize('r', [0.0, *RADII])
def test_path_around_a_square_has_the_analytic_length(r):
    start, goal = np.array([-3.0, 0.0]), np.array([3.0, 0.0])
    exact = around_square_length(3.0, SIDE / 2, r)
    if r == 0.0:
        assert exact == pytest.approx(2 + 2 * math.sqrt(5))  # via the corners (-1, 1), (1, 1)
    fine = VisibilityGraph(grow_obstacles([SQUARE], r, quad_segs=64))
    assert fine.cost_row(start, [goal])[0] == pytest.approx(exact, rel=2e-4)
    coarse = VisibilityGraph(grow_obstacles([SQUARE], r))
    cost = coarse.cost_row(start, [goal])[0]
    path = coarse.path(start, goal)
    assert exact - 1e-9 <= cost <= exact * 1.01        # circumscribed corners: a bit longer
    assert path_length(path) == pytest.approx(cost, rel=1e-12)
    np.testing.assert_array_equal(path[[0, -1]], [start, goal])


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_random_paths_never_cross_a_grown_obstacle(seed):
    rng = np.random.default_rng(seed)
    r = RADII[seed % len(RADII)]
    grown = grow_obstacles(random_obstacles(rng, 8), r)
    graph = VisibilityGraph(grown)
    starts, goals = free_points(rng, grown, 12), free_points(rng, grown, 12)
    costs = graph.cost_matrix(starts, goals)
    assert np.isfinite(costs).all()
    direct = np.linalg.norm(starts[:, None] - goals[None], axis=2)
    assert (costs >= direct - 1e-9).all()
    detoured = 0
    for i, s in enumerate(starts):
        for j, g in enumerate(goals):
            path = graph.path(s, g)
            assert_path_clear(path, grown)
            assert path_length(path) == pytest.approx(costs[i, j], rel=1e-9)
            detoured += len(path) > 2
    assert detoured > 10          # the obstacles are actually in the way


def test_unreachable_goals_cost_infinity():
    grown = grow_obstacles([box(-5, -5, 5, 5).difference(box(-4, -4, 4, 4)), SQUARE], 0.15)
    graph = VisibilityGraph(grown)
    goals = [[0.0, 3.0],            # in the courtyard enclosed by the ring wall
             [0.0, 0.0],            # inside an obstacle
             [10.0, 5.0]]           # free and visible
    cost = graph.cost_row([10.0, 0.0], goals)
    assert np.isinf(cost[:2]).all()
    assert cost[2] == pytest.approx(5.0)
    # From inside the courtyard the outside is unreachable in turn.
    assert np.isinf(graph.cost_row([0.0, 3.0], [[10.0, 0.0]])).all()


@pytest.mark.timeout(20)
@pytest.mark.parametrize('r', RADII)
def test_start_inside_an_obstacle_first_leaves_it_the_shortest_way(r):
    grown = grow_obstacles([SQUARE], r)
    graph = VisibilityGraph(grown)
    edge = grown[0].bounds[2]                  # x of the grown square's right side
    start, goal = np.array([0.9, 0.0]), np.array([3.0, 0.0])
    exit_point, escape = graph.escape(start)
    np.testing.assert_allclose(exit_point, [edge, 0.0], atol=1e-9)
    assert escape == pytest.approx(edge - 0.9)
    assert graph.cost_row(start, [goal])[0] == pytest.approx(3.0 - 0.9)
    # Going the other way: escape right, then around the square.
    back = graph.cost_row(start, [[-3.0, 0.0]])[0]
    path = graph.path(start, [-3.0, 0.0])
    np.testing.assert_allclose(path[1], [edge, 0.0], atol=1e-9)
    assert_path_clear(path[1:], grown)
    assert path_length(path) == pytest.approx(back, rel=1e-12)
    assert back > escape + around_square_length(3.0, SIDE / 2, r) / 2
    # A free start does not move.
    assert graph.escape(goal)[1] == 0.0
