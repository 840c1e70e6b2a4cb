"""Up-front refusal of shapes a swarm cannot cover (swarm_mission.coverability)."""

from __future__ import annotations

import math

import pytest
from shapely.geometry import box

from swarm_common.robot_types import load_robot_types
from swarm_common.shapes import load_shape, Shape, shape_from_polygon, ShapeError
from swarm_mission.coverability import (
    check_coverable,
    coverability_problem,
    required_area,
)
from swarm_mission.mission import Mission, MissionConfig

RADII = {t: r.coverage_radius for t, r in load_robot_types().items()}   # 0.15 / 0.3 / 0.5 m
THESIS = {1: 20, 2: 20, 3: 10}


def _square(side: float, name: str = 'square', obstacles=()) -> Shape:
    return shape_from_polygon(box(-side / 2, -side / 2, side / 2, side / 2),
                              list(obstacles), name=name)


def _fence(x0: float, y0: float, x1: float, y1: float, gap: float) -> list:
    """Four 0.4 m thick walls around [x0, x1] x [y0, y1], a ``gap`` m opening in the
    middle of the top wall (no opening for gap 0)."""
    t = 0.4
    walls = [box(x0 - t, y0 - t, x1 + t, y0), box(x0 - t, y0, x0, y1),
             box(x1, y0, x1 + t, y1)]
    if gap > 0:
        mid = (x0 + x1) / 2
        walls += [box(x0 - t, y1, mid - gap / 2, y1 + t), box(mid + gap / 2, y1, x1 + t,
                                                               y1 + t)]
    else:
        walls.append(box(x0 - t, y1, x1 + t, y1 + t))
    return walls


def test_thesis_swarm_needs_the_sum_of_its_coverage_discs():
    need = 20 * math.pi * 0.15 ** 2 + 20 * math.pi * 0.3 ** 2 + 10 * math.pi * 0.5 ** 2
    assert required_area(THESIS, RADII) == pytest.approx(need)          # 14.92 m^2
    too_small = _square(math.sqrt(need) * 0.99)
    with pytest.raises(ShapeError, match=r'too small: .* 50 robots \(14.9 m\^2'):
        check_coverable(too_small, THESIS, RADII)
    assert coverability_problem(_square(math.sqrt(need) * 1.01), THESIS, RADII) is None


def test_every_thesis_shape_is_coverable():
    for name in ('circle_314', 'table43_2', 'table43_3', 'table43_4', 'flower_314',
                 'thesis_shape_1', 'thesis_shape_2', 'thesis_shape_3', 'thesis_shape_4',
                 'thesis_workspace'):
        assert coverability_problem(load_shape(name), THESIS, RADII) is None, name


def test_a_shape_fenced_in_by_obstacles_is_refused_until_the_gap_passes_a_robot():
    # Type 3 (r = 0.5 m) passes a gap only if it is wider than its 1 m diameter.
    closed = _square(10.0, 'fenced', _fence(-8, -8, 8, 8, gap=0.8))
    with pytest.raises(ShapeError, match='walled off from it.*radius 0.5 m.*wider than 1 m'):
        check_coverable(closed, THESIS, RADII)
    assert coverability_problem(_square(10.0, 'open', _fence(-8, -8, 8, 8, gap=1.2)),
                                THESIS, RADII) is None
    # Without type 3 the largest robot (r = 0.3 m) passes the 0.8 m gap.
    assert coverability_problem(closed, {1: 20, 2: 20}, RADII) is None


def test_part_of_the_region_walled_off_is_refused_naming_where():
    region = _square(30.0, 'walled', _fence(5, 5, 12, 12, gap=0.0))
    problem = coverability_problem(region, THESIS, RADII)
    assert 'm^2 of the region around (' in problem and 'walled off from the rest' in problem
    x, y = (float(v) for v in problem.split('around (')[1].split(')')[0].split(','))
    assert 5 < x < 12 and 5 < y < 12


def test_robots_starting_in_an_enclosed_pocket_cannot_reach_the_shape():
    shape = _square(12.0, 'pocket', _fence(20, 20, 30, 30, gap=0.0))
    with pytest.raises(ShapeError, match='robots starting in the .* walled off'):
        check_coverable(shape, THESIS, RADII)
    # Given start positions outside the pocket, the shape is reachable from all of them.
    assert coverability_problem(shape, THESIS, RADII, starts=[(-30, -30), (40, 0)]) is None
    with pytest.raises(ShapeError, match=r'start position 1 at \(25.0, 25.0\)'):
        check_coverable(shape, THESIS, RADII, starts=[(-30, -30), (25, 25)])


def test_a_neck_narrower_than_the_largest_robot_is_refused_saying_where():
    def dumbbell(neck: float) -> Shape:
        region = box(-12, -5, -2, 5).union(box(2, -5, 12, 5)).union(
            box(-2.5, -neck / 2, 2.5, neck / 2))
        return shape_from_polygon(region, name='dumbbell')

    with pytest.raises(ShapeError, match=r'neck narrower than a robot \(1 m.*near \(0.0, '
                                         r'0.0\).*splits into 2 parts'):
        check_coverable(dumbbell(0.9), THESIS, RADII)
    assert coverability_problem(dumbbell(1.1), THESIS, RADII) is None


def test_a_strip_narrower_than_the_largest_robot_vanishes():
    strip = shape_from_polygon(box(-20, -0.45, 20, 0.45), name='strip')   # 36 m^2, 0.9 m
    with pytest.raises(ShapeError, match="'strip' vanishes when shrunk by .* 0.5 m"):
        check_coverable(strip, THESIS, RADII)
    assert coverability_problem(strip, {1: 20, 2: 20}, RADII) is None   # r <= 0.3 m fits


def test_the_mission_refuses_an_uncoverable_shape_without_adopting_it():
    mission = Mission(MissionConfig(), agent_types={i: 1 + i % 3 for i in range(30)},
                      radii=RADII)
    assert mission.set_shape(load_shape('circle_314'))
    with pytest.raises(ShapeError, match='too small'):
        mission.set_shape(_square(2.0, 'tiny'))
    assert (mission.shape.name, mission.shape_version) == ('circle_314', 1)
