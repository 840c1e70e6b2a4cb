"""Shape loading and validation (swarm_common.shapes, builtin_shapes)."""

from __future__ import annotations

import json

import numpy as np
from PIL import Image, ImageDraw
import pytest
from shapely.geometry import Polygon
from shapely.ops import unary_union

from swarm_common.builtin_shapes import builtin_obstacles, TABLE43_LENGTHS
from swarm_common.shapes import builtin_shape_names, load_shape, shape_from_rings, ShapeError

SQUARE = [[0, 0], [10, 0], [10, 10], [0, 10]]


def test_every_builtin_loads_valid_and_finite():
    for name in builtin_shape_names():
        shape = load_shape(name)
        assert shape.region.is_valid and shape.area > 0
        assert np.isfinite(np.asarray(shape.region.exterior.coords)).all()


def test_thesis_areas_and_table43_boundary_lengths():
    assert load_shape('circle_314').area == pytest.approx(314.0, rel=1e-6)
    for i, length in enumerate(TABLE43_LENGTHS, start=1):
        shape = load_shape(f'table43_{i}')
        assert shape.area == pytest.approx(314.0, rel=1e-6)
        assert shape.boundary_length == pytest.approx(length, abs=0.05)
    for i in range(1, 5):
        assert load_shape(f'thesis_shape_{i}').area == pytest.approx(314.0, rel=1e-6)


def test_workspace_obstacles_inside_workspace_and_clear_of_every_shape():
    obstacles = unary_union(builtin_obstacles())
    assert Polygon([(-50, -50), (50, -50), (50, 50), (-50, 50)]).contains(obstacles)
    for name in builtin_shape_names():
        assert load_shape(name).region.distance(obstacles) > 5.0, name
    assert len(load_shape('thesis_workspace').obstacles) == 4


def test_hardware_shapes_fit_the_arena():
    arena = Polygon([(-1, -1), (1, -1), (1, 1), (-1, 1)])
    for name in ('hw_trapezoid', 'hw_square', 'hw_pentagon', 'hw_arrow', 'hw_line'):
        shape = load_shape(name)
        assert arena.contains(shape.region)
        # room for 5 robots of radius 0.16 m at hexagonal density
        assert shape.area > 5 * np.pi * 0.16 ** 2 / 0.9069


def test_a_shape_answers_inside_as_its_bare_outline_does():
    """The region is prepared for the many point queries (eq. 4.1 at every heartbeat):
    the same answers as an unprepared copy, on the boundary, in holes and outside."""
    import shapely

    rng = np.random.default_rng(3)
    for name in builtin_shape_names():
        shape = load_shape(name)
        bare = Polygon(shape.region.exterior.coords,
                       [ring.coords for ring in shape.region.interiors])
        assert shapely.is_prepared(shape.region) and not shapely.is_prepared(bare)
        lo, hi = np.array(shape.region.bounds[:2]), np.array(shape.region.bounds[2:])
        points = np.vstack([lo + (hi - lo) * rng.random((400, 2)),
                            np.array(shape.region.exterior.coords)])   # on the boundary
        assert np.array_equal(shapely.contains_xy(shape.region, points[:, 0], points[:, 1]),
                              shapely.contains_xy(bare, points[:, 0], points[:, 1]))


def test_json_round_trip_with_hole_and_obstacle(tmp_path):
    path = tmp_path / 'l.json'
    path.write_text(json.dumps({'outer': SQUARE, 'holes': [[[2, 2], [4, 2], [4, 4], [2, 4]]],
                                'obstacles': [[[20, 20], [22, 20], [21, 22]]]}))
    shape = load_shape(str(path))
    assert shape.area == pytest.approx(100 - 4)
    assert len(shape.obstacles) == 1 and shape.name == 'l'
    assert load_shape(str(path), scale=2.0).area == pytest.approx(4 * 96)
    centred = load_shape(str(path), center=True)
    assert np.allclose(centred.centroid, 0.0, atol=1e-9)


def test_svg_first_closed_path_with_hole_scaled(tmp_path):
    path = tmp_path / 's.svg'
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 5 0"/>'
                    '<path d="M 0 0 h 100 v 50 H 0 Z M 10 10 l 10 0 l 0 10 l -10 0 z"/></svg>')
    shape = load_shape(str(path), scale=0.1)
    assert shape.area == pytest.approx((5000 - 100) * 0.01)
    assert len(shape.region.interiors) == 1


def test_png_silhouette_largest_dark_region(tmp_path):
    image = Image.new('L', (200, 200), 255)
    draw = ImageDraw.Draw(image)
    draw.ellipse([20, 20, 180, 180], fill=0)          # radius 80 px
    draw.rectangle([2, 2, 8, 8], fill=0)              # small speck: ignored
    path = tmp_path / 'disc.png'
    image.save(path)
    shape = load_shape(str(path), metres_per_pixel=0.05)
    assert shape.area == pytest.approx(np.pi * 4.0 ** 2, rel=0.03)
    assert np.allclose(shape.centroid, 0.0, atol=1e-6)


def test_shape_from_rings_accepts_open_and_closed_rings():
    open_ring = shape_from_rings(SQUARE)
    closed = shape_from_rings(SQUARE + [SQUARE[0]])
    assert open_ring.region.equals(closed.region)


@pytest.mark.parametrize('outer, holes, needle', [
    ([[0, 0], [10, 10], [10, 0], [0, 10]], [], 'self-intersection'),
    ([], [], 'empty'),
    ([[0, 0], [1, 0]], [], 'fewer than 3'),
    ([[0, 0], [np.nan, 0], [1, 1]], [], 'NaN'),
    ([[0, 0], [1, 0], [2, 0]], [], 'no area'),
    (SQUARE, [[[8, 8], [12, 8], [12, 12], [8, 12]]], 'outside the outer ring'),
    (SQUARE, [[[2, 2], [5, 2], [5, 5], [2, 5]], [[4, 4], [6, 4], [6, 6], [4, 6]]], 'overlap'),
])
def test_bad_rings_raise_shape_error_naming_the_problem(outer, holes, needle):
    with pytest.raises(ShapeError, match=needle):
        shape_from_rings(outer, holes)


@pytest.mark.parametrize('name, content, needle', [
    ('open.svg', '<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 9 0 L 9 9"/></svg>',
     'no closed path'),
    ('bad.svg', '<svg><path d=', 'not a readable SVG'),
    ('bad.png', 'not a png', 'not a readable image'),
    ('bad.json', '{"outer": ', 'not valid JSON'),
    ('nokey.json', '{"rings": []}', '"outer"'),
])
def test_bad_files_raise_shape_error(tmp_path, name, content, needle):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(ShapeError, match=needle):
        load_shape(str(path))


def test_blank_png_unknown_name_and_bad_scale(tmp_path):
    path = tmp_path / 'white.png'
    Image.new('L', (20, 20), 255).save(path)
    with pytest.raises(ShapeError, match='no dark region'):
        load_shape(str(path))
    with pytest.raises(ShapeError, match='built-in names'):
        load_shape('no_such_shape')
    with pytest.raises(ShapeError, match='does not exist'):
        load_shape(str(tmp_path / 'missing.json'))
    with pytest.raises(ShapeError, match='positive'):
        load_shape('circle_314', scale=-1.0)
