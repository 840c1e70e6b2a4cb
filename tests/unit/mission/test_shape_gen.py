"""Procedural study shapes (swarm_mission.shape_gen): valid, sized, coverable, seeded."""

from __future__ import annotations

import math

import pytest
import shapely
from shapely.geometry import Polygon

from swarm_common.robot_types import default_type_counts, load_robot_types
from swarm_mission.coverability import coverability_problem
from swarm_mission.shape_gen import (
    AREA_PER_AGENT,
    EDGE_CLEARANCE,
    generate,
    KINDS,
    neck_width,
    OBSTACLE_CLEARANCE,
    ShapeGenError,
    study_shapes,
    WORKSPACE_HALF_SIZE,
)

RADII = {t: r.coverage_radius for t, r in load_robot_types().items()}
SEEDS = range(40)


def _parts(geometry) -> int:
    return 0 if geometry.is_empty else len(getattr(geometry, 'geoms', [geometry]))


@pytest.mark.parametrize('kind', KINDS)
@pytest.mark.parametrize('agents', [50, 6])
def test_every_generated_shape_is_valid_sized_placed_and_coverable(kind, agents):
    target = AREA_PER_AGENT * agents          # 314 m^2 for 50 agents (thesis chapter 4)
    counts = default_type_counts(agents)
    limit = WORKSPACE_HALF_SIZE - EDGE_CLEARANCE
    for seed in SEEDS:
        shape = generate(kind, seed, agents)
        region = shape.region
        assert isinstance(region, Polygon) and region.is_valid, (kind, seed)
        assert abs(shape.area / target - 1.0) < 0.10, (kind, seed, shape.area)
        outer = Polygon(region.exterior)
        assert all(outer.contains(Polygon(h)) for h in region.interiors), (kind, seed)
        assert shape.centroid == pytest.approx([0.0, 0.0], abs=1e-6)
        everything = shapely.union_all([region, *shape.obstacles])
        assert max(abs(v) for v in everything.bounds) <= limit, (kind, seed)
        assert coverability_problem(shape, counts, RADII) is None, (kind, seed)


def test_the_kinds_have_what_their_names_promise():
    for seed in SEEDS:
        holes = generate('holes', seed)
        assert 1 <= len(holes.region.interiors) <= 3
        for kind in ('concave', 'spiral'):
            region = generate(kind, seed).region
            assert region.area < 0.9 * region.convex_hull.area, (kind, seed)
        obstacles = generate('obstacles', seed)
        assert len(obstacles.obstacles) >= 2
        for i, a in enumerate(obstacles.obstacles):
            assert a.distance(obstacles.region) >= OBSTACLE_CLEARANCE - 1e-9
            assert all(a.distance(b) >= OBSTACLE_CLEARANCE - 1e-9
                       for b in obstacles.obstacles[i + 1:])
        # The neck is two coverage diameters of type 3 (2 m, up to 10 % wider): the
        # region shrunk by half the widest neck splits in two, by a robot's radius it
        # does not.
        neck = generate('neck', seed).region
        assert neck_width() == pytest.approx(2.0)
        assert _parts(neck.buffer(-1.1 * neck_width() / 2 - 0.05)) >= 2, seed
        assert _parts(neck.buffer(-0.5)) == 1, seed


def test_a_kind_and_seed_always_give_the_same_shape_and_seeds_differ():
    for kind in KINDS:
        a, b = generate(kind, 7), generate(kind, 7)
        assert a.region.equals_exact(b.region, 0.0) and a.name == f'{kind}_7'
        assert len(a.obstacles) == len(b.obstacles)
        assert not generate(kind, 8).region.equals_exact(a.region, 1e-3)


def test_study_shapes_cycle_through_the_kinds_with_unique_names():
    shapes = study_shapes(14, 3)
    assert [s.name.rsplit('_', 1)[0] for s in shapes] == [KINDS[i % 6] for i in range(14)]
    assert len({s.name for s in shapes}) == 14
    assert shapes[0].area == pytest.approx(314.0)


def test_bad_requests_are_refused_with_the_reason():
    with pytest.raises(ShapeGenError, match="unknown shape kind 'square'; use one of blob"):
        generate('square', 0)
    with pytest.raises(ShapeGenError, match='n_agents must be a positive integer'):
        generate('blob', 0, 0)
    assert math.isclose(generate('blob', 0, 10).area, 10 * AREA_PER_AGENT)
