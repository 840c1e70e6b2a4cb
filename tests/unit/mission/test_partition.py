"""Bubble packing and randomized fractals through the partition entry point."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from shapely.geometry import box
from shapely.geometry import Point as ShapelyPoint

from swarm_common.goals import goal_positions, goal_radii, placement_violations
from swarm_common.robot_types import default_type_counts, load_robot_types
from swarm_common.shapes import load_shape, Shape, shape_from_rings, ShapeError
from swarm_mission.bubble_packing import auto_spacing, BubbleConfig, interbubble_force
from swarm_mission.fractals import schedule_offset, zeta_areas
from swarm_mission.mission import MissionConfig
from swarm_mission.partition import (
    load_partition_config,
    partition,
    PartitionConfig,
    PartitionError,
)

RADII = {t: r.coverage_radius for t, r in load_robot_types().items()}
SWARM = default_type_counts(50)          # thesis 20:20:10


def assert_feasible(result, shape, counts, type_radii=RADII):
    pts, radii = goal_positions(result.goals), goal_radii(result.goals)
    outside, overlaps = placement_violations(pts, radii, shape.region)
    assert len(outside) == 0, f'circles outside the shape: {outside}'
    assert len(overlaps) == 0, f'overlapping circles: {overlaps}'
    assert Counter(g.type for g in result.goals) == Counter(counts)
    assert all(g.radius == type_radii[g.type] for g in result.goals)
    assert len({g.id for g in result.goals}) == len(result.goals)


@pytest.mark.parametrize('method', ['bubble', 'fractal'])
@pytest.mark.parametrize('name', ['circle_314', 'thesis_shape_3', 'table43_4'])
def test_goals_inside_without_overlap_and_match_the_swarm(method, name):
    shape = load_shape(name)
    result = partition(shape, SWARM, RADII, method, seed=1)
    assert_feasible(result, shape, SWARM)
    assert result.method == method and result.iterations > 0


def test_hardware_shapes_partition_for_five_robots():
    radii = {1: 0.16, 2: 0.11, 3: 0.08}
    for name in ('hw_trapezoid', 'hw_square', 'hw_pentagon', 'hw_arrow', 'hw_line'):
        shape = load_shape(name)
        result = partition(shape, {1: 1, 2: 2, 3: 2}, radii, 'bubble', seed=0)
        assert_feasible(result, shape, {1: 1, 2: 2, 3: 2}, radii)


@pytest.mark.parametrize('method', ['bubble', 'fractal'])
def test_same_seed_same_partition(method):
    shape = load_shape('thesis_shape_1')
    a = partition(shape, SWARM, RADII, method, seed=7)
    b = partition(shape, SWARM, RADII, method, seed=7)
    assert a.goals == b.goals
    c = partition(shape, SWARM, RADII, method, seed=8)
    assert [(g.x, g.y, g.type) for g in c.goals] != [(g.x, g.y, g.type) for g in a.goals]


def test_bubble_packing_beats_fractals_and_meets_the_target_on_a_thesis_shape():
    shape = load_shape('thesis_shape_1')
    bp = [partition(shape, SWARM, RADII, 'bubble', seed=s) for s in range(3)]
    rf = [partition(shape, SWARM, RADII, 'fractal', seed=s) for s in range(3)]
    for key in ('epsilon_t', 'epsilon_g', 'epsilon_g_with_boundary'):
        assert np.mean([getattr(r, key) for r in bp]) < np.mean([getattr(r, key) for r in rf])
    assert np.mean([r.epsilon_t for r in bp]) <= 0.5
    assert np.mean([r.epsilon_g for r in bp]) <= 0.08


def test_epsilon_t_rises_with_boundary_length_at_constant_area():
    # Table 4.3: same area (314 m^2) and swarm, boundary 62.8 -> 128.36 m. The thesis's
    # trend comes with its own shape repulsion (eq. 3.97, boundary 'thesis') and with the
    # row held half a spacing inside ('mirror'). With the default row on the contour
    # ('layer') the straight 52 x 6 m strip is an almost perfect three-row lattice, so
    # only the complex contour stays the most irregular: the improvement, not a miss.
    configs = {name: PartitionConfig(bubble=BubbleConfig(boundary=name))
               for name in ('thesis', 'mirror', 'layer')}
    for name, config in configs.items():
        means = [np.mean([partition(load_shape(f'table43_{i}'), SWARM, RADII, 'bubble',
                                    seed=s, config=config).epsilon_t for s in range(3)])
                 for i in range(1, 5)]
        if name == 'layer':
            assert means[3] == max(means), means
        else:
            assert all(np.diff(means) > 0), (name, means)


@pytest.mark.parametrize('name', ['circle_314', 'thesis_shape_1', 'thesis_shape_2',
                                  'thesis_shape_3', 'thesis_shape_4'])
def test_issue_4_mesh_quality_target_on_thesis_like_shapes(name):
    # Issue 4: 50 agents 20:20:10, mean epsilon_t <= 0.5 and epsilon_g <= 0.08 over
    # seeds (interior definition), met by the default, the boundary row on the contour
    # ('layer'). Missed on thesis_shape_3 (eps_t 0.60) and _4 (eps_g 0.09) with the row
    # half a spacing inside ('mirror'): its Delaunay hull slivers have their centroids
    # inside the shape (bubble_packing doc).
    shape = load_shape(name)
    assert BubbleConfig().boundary == 'layer'
    runs = [partition(shape, SWARM, RADII, 'bubble', seed=s) for s in range(4)]
    assert np.mean([r.epsilon_t for r in runs]) <= 0.5
    assert np.mean([r.epsilon_g for r in runs]) <= 0.08
    for r in runs:
        assert_feasible(r, shape, SWARM)


def test_incremental_remesh_keeps_ids_and_stays_close_on_an_unchanged_shape():
    shape = load_shape('thesis_shape_1')
    first = partition(shape, SWARM, RADII, 'bubble', seed=0)
    again = partition(shape, SWARM, RADII, 'bubble', seed=0, previous=first.goals)
    assert {g.id: g.type for g in again.goals} == {g.id: g.type for g in first.goals}
    moved = np.linalg.norm(goal_positions(sorted(again.goals, key=lambda g: g.id))
                           - goal_positions(sorted(first.goals, key=lambda g: g.id)), axis=1)
    assert np.median(moved) < 0.1 * first.spacing


def test_incremental_remesh_of_a_changed_shape_and_a_lost_agent():
    first = partition(load_shape('table43_1'), SWARM, RADII, 'bubble', seed=0)
    new_shape = load_shape('table43_2')
    survivors = dict(SWARM)
    survivors[2] -= 1
    result = partition(new_shape, survivors, RADII, 'bubble', seed=0, previous=first.goals)
    assert_feasible(result, new_shape, survivors)
    assert {g.id for g in result.goals} < {g.id for g in first.goals}


@pytest.mark.parametrize('seed', range(6))
def test_incremental_remesh_onto_a_shape_the_old_goals_barely_overlap(seed):
    """Goals of a circle about the origin, projected into a room with a hole that meets
    the circle only near its corner, crowd onto a few points; the re-mesh must still give
    a valid partition (it refused the room in 15 of 20 seeds, telling the user to
    enlarge a shape twelve times larger than the circles)."""
    counts, radii = {1: 2, 2: 2, 3: 1}, {1: 1.0, 2: 1.2, 3: 1.5}
    first = partition(load_shape('circle_314'), counts, radii, 'bubble', seed=seed,
                      margin=0.6)
    room = shape_from_rings([[0, 0], [20, 0], [20, 15], [0, 15]],
                            [[[8, 5], [12, 5], [12, 9]]], name='room')
    result = partition(room, counts, radii, 'bubble', seed=seed, previous=first.goals,
                       margin=0.6)
    assert_feasible(result, room, counts, radii)
    assert {g.id for g in result.goals} == {g.id for g in first.goals}


def test_fractal_stops_cleanly_when_the_free_space_is_full():
    small = load_shape('circle_314').scaled(0.26)            # 21 m^2 for 16.4 m^2 of circles
    with pytest.raises(PartitionError, match=r'free space is full after \d+ of 50') as info:
        partition(small, SWARM, RADII, 'fractal', seed=0)
    assert 'times larger' in str(info.value)


def test_shape_too_small_for_any_packing_says_by_how_much():
    tiny = load_shape('circle_314').scaled(0.1)               # 3.14 m^2
    for method in ('bubble', 'fractal'):
        with pytest.raises(PartitionError, match='scale the shape by at least') as info:
            partition(tiny, SWARM, RADII, method)
        factor = float(str(info.value).rsplit(' ', 1)[-1])
        assert factor == pytest.approx(np.sqrt(14.92 / 0.9069 / tiny.area), rel=0.01)


@pytest.mark.parametrize('counts, radii, method, needle', [
    ({}, RADII, 'bubble', 'empty'),
    ({1: 0}, RADII, 'bubble', 'no agents'),
    ({1: -3}, RADII, 'bubble', 'non-negative'),
    ({1: 2.5}, RADII, 'bubble', 'integer'),
    ({4: 2}, RADII, 'bubble', 'no coverage radius'),
    ({1: 2}, {1: float('nan')}, 'bubble', 'positive and finite'),
    ({1: 2}, RADII, 'voronoi', 'unknown partition method'),
])
def test_bad_swarm_or_method(counts, radii, method, needle):
    with pytest.raises(PartitionError, match=needle):
        partition(load_shape('circle_314'), counts, radii, method)


def test_force_law_and_schedule_first_principles():
    # Thesis eq. 3.95 values: f(l0 = 2.5) = 0.4375, f(l > l0) = 0 (DESIGN.md).
    c = BubbleConfig()
    assert interbubble_force(2.5, c.a, c.b, c.c, c.d, c.l0) == pytest.approx(0.4375)
    assert interbubble_force(2.6, c.a, c.b, c.c, c.d, c.l0) == 0.0
    # Shimada law: zero force at the target distance, attraction just beyond it.
    assert interbubble_force(1.0, 1.25, -2.375, 0.0, 1.125, 1.5) == pytest.approx(0.0)
    assert interbubble_force(1.25, 1.25, -2.375, 0.0, 1.125, 1.5) < 0
    # Hexagonal cell of area A/n: sqrt(3)/2 s^2 = A/n.
    s = auto_spacing(314.0, 50)
    assert np.sqrt(3) / 2 * s ** 2 * 50 == pytest.approx(314.0)
    # Eqs. 3.99-3.101: n claims sum to the requested share of the area.
    big_n = schedule_offset(50, 1.3, 0.5)
    assert zeta_areas(314.0, 50, 1.3, big_n).sum() == pytest.approx(157.0, rel=1e-6)


def test_yaml_defaults_match_the_dataclasses():
    assert load_partition_config() == PartitionConfig()


@pytest.mark.parametrize('options', [{'force': 'thesis', 'spacing': 'thesis'},
                                     {'boundary': 'thesis'}])
def test_thesis_parameter_modes_stay_feasible(options):
    shape = load_shape('thesis_shape_1')
    config = PartitionConfig(bubble=BubbleConfig(**options, max_iterations=150))
    result = partition(shape, SWARM, RADII, 'bubble', seed=0, config=config)
    assert_feasible(result, shape, SWARM)


def test_bad_bubble_parameters_name_the_field():
    with pytest.raises(PartitionError, match='force'):
        BubbleConfig(force='magnetic')


@pytest.mark.parametrize('method', ['bubble', 'fractal'])
def test_a_margin_keeps_every_coverage_circle_that_far_inside_the_contour(method):
    # The running system's band for localization error (mission formation_margin_m):
    # every goal's circle lies at least the margin inside the shape itself.
    shape = load_shape('thesis_shape_2')
    result = partition(shape, SWARM, RADII, method, seed=3, margin=0.6)
    assert result.margin == 0.6
    assert_feasible(result, shape.inset(0.6), SWARM)
    boundary = shape.region.boundary
    gaps = [boundary.distance(ShapelyPoint(g.x, g.y)) - g.radius for g in result.goals]
    assert min(gaps) >= 0.6 - 1e-6
    plain = partition(shape, SWARM, RADII, method, seed=3)
    assert plain.margin == 0.0 and min(boundary.distance(ShapelyPoint(g.x, g.y)) - g.radius
                                       for g in plain.goals) < 0.6


def test_a_margin_the_shape_cannot_afford_falls_back_to_the_shape_itself():
    # 8 agents fill a 4 x 4 m square (about 2.4 m^2 of circles): shrunk by 1.5 m it is a
    # 1 x 1 m square, too small, so the square itself is partitioned (result.margin 0).
    square = Shape('square', box(0, 0, 4, 4))
    counts = {1: 4, 2: 4}
    result = partition(square, counts, RADII, 'bubble', seed=0, margin=1.5)
    assert result.margin == 0.0
    assert_feasible(result, square, counts)
    with pytest.raises(PartitionError, match='margin must be a finite number >= 0'):
        partition(square, counts, RADII, 'bubble', margin=-0.1)


def test_inset_shapes_and_their_errors():
    square = Shape('sq', box(0, 0, 10, 10))
    assert square.inset(0) is square
    assert square.inset(1.0).area == pytest.approx(64.0)
    with pytest.raises(ShapeError, match='vanishes when shrunk by 6 m'):
        square.inset(6.0)
    dumbbell = Shape('dumbbell', box(0, 0, 4, 4).union(box(4, 1.8, 8, 2.2)).union(
        box(8, 0, 12, 4)))
    with pytest.raises(ShapeError, match='splits into 2 parts when shrunk by 0.5 m'):
        dumbbell.inset(0.5)
    with pytest.raises(ShapeError, match='finite number >= 0'):
        square.inset(float('nan'))
    with pytest.raises(ShapeError, match='formation_margin_m'):
        MissionConfig(formation_margin=-1.0)
