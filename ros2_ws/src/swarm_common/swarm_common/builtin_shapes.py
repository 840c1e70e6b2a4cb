"""Built-in formation shapes of the thesis scenarios and the thesis workspace obstacles.

Stable names (``load_shape(name)``), all in metres, map frame, centred near the origin:

=====================  ==================================================================
``circle_314``         the 314 m^2 circle of chapter 4 (r = 10 m, 256 vertices)
``table43_1`` .. ``_4`` the Table 4.3 sequence at constant area 314 m^2 and boundary
                       length 62.8 / 82.8 / 116.82 / 128.36 m: circle, 31.4 x 10 m
                       rectangle, 52.42 x 5.99 m rectangle, a meandering band (complex
                       contour, about 5.3 m wide)
``flower_314``         six-lobed contour, 314 m^2, boundary 128.36 m (a rounder complex
                       contour of the same area and length as ``table43_4``)
``thesis_shape_1``..4  shapes resembling Figs. 4.41-4.48 (kidney, boomerang, ring with an
                       off-centre hole, four-armed star), each 314 m^2 and carrying the
                       workspace obstacles below
``thesis_workspace``   ``circle_314`` with the workspace obstacles
``hw_trapezoid``,      the five hardware shapes of Figs. 5.11-5.20 (trapezoid, square,
``hw_square``,         pentagon, arrow, line), 0.5-0.8 m^2, sized for 5 robots of coverage
``hw_pentagon``,       radii 0.16/0.11/0.08 m and centred in a 2 x 2 m arena whose centre
``hw_arrow``,          is the origin
``hw_line``
=====================  ==================================================================

The figures of the thesis are only available as captions here, so ``thesis_shape_*``
are hand-drawn non-analytic contours of the same size and kind (complex closed
contours of about 20 m across), not traces of the figures.

``builtin_obstacles()`` is the thesis-scenario obstacle set: four polygons inside the
+/-50 m workspace, at least 5 m clear of every built-in formation shape placed at the
centre.
"""

from __future__ import annotations

from collections.abc import Callable
import functools

import numpy as np
from scipy.optimize import brentq
from shapely.geometry import LineString, Polygon

from swarm_common.shapes import Shape, shape_from_rings

THESIS_AREA = 314.0        # m^2, chapter 4 formation area
TABLE43_LENGTHS = (62.8, 82.8, 116.82, 128.36)   # m, Table 4.3 boundary lengths


def _regular(n: int, radius: float, phase: float = 0.0) -> np.ndarray:
    t = phase + 2 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def _scale_to_area(ring: np.ndarray, area: float, holes: tuple = ()) -> tuple:
    poly = Polygon(ring, list(holes))
    k = np.sqrt(area / poly.area)
    c = np.array([poly.centroid.x, poly.centroid.y])
    return (ring - c) * k, tuple((h - c) * k for h in holes)


def builtin_obstacles() -> tuple[Polygon, ...]:
    """Workspace obstacles of the thesis scenario (inside +/-50 m, clear of the shapes)."""
    rings = [
        np.array([[29.0, 27.0], [35.0, 27.0], [35.0, 33.0], [29.0, 33.0]]),      # box
        np.array([[-38.0, 25.0], [-30.0, 26.0], [-35.0, 33.0]]),                  # triangle
        _regular(5, 4.0, 0.3) + [-31.0, -32.0],                                   # pentagon
        np.array([[30.0, -32.0], [38.0, -32.0], [38.0, -28.0], [30.0, -28.0]]),   # wall
    ]
    return tuple(Polygon(r) for r in rings)


def _rect(length: float, width: float) -> np.ndarray:
    a, b = length / 2, width / 2
    return np.array([[-a, -b], [a, -b], [a, b], [-a, b]])


def _circle(area: float, n: int = 256) -> np.ndarray:
    # Radius of the n-gon of exactly ``area``: area = n/2 R^2 sin(2 pi / n).
    return _regular(n, np.sqrt(2 * area / (n * np.sin(2 * np.pi / n))))


def _rect_with(perimeter: float, area: float) -> np.ndarray:
    half = perimeter / 2
    length = (half + np.sqrt(half ** 2 - 4 * area)) / 2
    return _rect(length, area / length)


@functools.cache
def _meander(area: float, perimeter: float, amplitude: float = 0.15) -> np.ndarray:
    """Band around a sine centre line, half-length k and half-width h solved for the
    ``area`` and ``perimeter`` of Table 4.3 shape 4 (a complex contour)."""
    x = np.linspace(-1.0, 1.0, 200)

    def band(k: float, h: float) -> Polygon:
        line = LineString(np.column_stack([k * x, k * amplitude * np.sin(2 * np.pi * x)]))
        return line.buffer(h, cap_style='flat', join_style='round', quad_segs=16)

    def half_width(k: float) -> float:
        return brentq(lambda h: band(k, h).area - area, 0.5, 8.0, xtol=1e-10)

    k = brentq(lambda k: band(k, half_width(k)).length - perimeter, 14.0, 34.0, xtol=1e-10)
    return np.asarray(band(k, half_width(k)).exterior.coords)[:-1]


@functools.cache
def _flower(area: float, perimeter: float, lobes: int = 6) -> np.ndarray:
    """Six-lobed contour r = 1 + e cos(6 t), scaled to ``area``, e chosen for ``perimeter``."""
    t = 2 * np.pi * np.arange(720) / 720

    def ring(e: float) -> np.ndarray:
        r = 1 + e * np.cos(lobes * t)
        return _scale_to_area(np.column_stack([r * np.cos(t), r * np.sin(t)]), area)[0]

    e = brentq(lambda e: Polygon(ring(e)).length - perimeter, 0.0, 0.9, xtol=1e-9)
    return ring(e)


_KIDNEY = np.array([[0, 0], [6, -3], [13, -2], [18, 3], [18, 10], [14, 15], [9, 14],
                    [7, 10], [3, 11], [-1, 14], [-5, 12], [-6, 6], [-4, 2]], dtype=float)
_BOOMERANG = np.array([[0, 0], [12, 0], [22, 4], [24, 10], [18, 9], [10, 7], [6, 9],
                       [4, 18], [-2, 20], [-4, 12], [-3, 4]], dtype=float)
_RING_OUTER = np.array([[0, 0], [8, -4], [17, -2], [22, 5], [20, 14], [12, 19], [3, 17],
                        [-3, 10]], dtype=float)
_RING_HOLE = np.array([[6, 5], [11, 3], [13, 8], [9, 11]], dtype=float)


def _star(arms: int = 4) -> np.ndarray:
    t = np.pi * np.arange(2 * arms) / arms + 0.2
    r = np.where(np.arange(2 * arms) % 2 == 0, 1.0, 0.42)
    r = r * (1 + 0.08 * np.sin(3 * t))      # irregular arms: no analytic symmetry
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def _thesis(name: str, ring: np.ndarray, holes: tuple = ()) -> Shape:
    outer, holes = _scale_to_area(ring, THESIS_AREA, holes)
    return shape_from_rings(outer, holes, [np.asarray(o.exterior.coords)
                                           for o in builtin_obstacles()], name=name)


def _plain(name: str, ring: np.ndarray) -> Shape:
    return shape_from_rings(ring, name=name)


_HW_AREA = 0.64   # m^2: five robots of radius <= 0.16 m at ~0.4 m spacing


BUILTIN_SHAPES: dict[str, Callable[[], Shape]] = {
    'circle_314': lambda: _plain('circle_314', _circle(THESIS_AREA)),
    'table43_1': lambda: _plain('table43_1', _circle(THESIS_AREA)),
    'table43_2': lambda: _plain('table43_2', _rect_with(TABLE43_LENGTHS[1], THESIS_AREA)),
    'table43_3': lambda: _plain('table43_3', _rect_with(TABLE43_LENGTHS[2], THESIS_AREA)),
    'table43_4': lambda: _plain('table43_4', _meander(THESIS_AREA, TABLE43_LENGTHS[3])),
    'flower_314': lambda: _plain('flower_314', _flower(THESIS_AREA, TABLE43_LENGTHS[3])),
    'thesis_shape_1': lambda: _thesis('thesis_shape_1', _KIDNEY),
    'thesis_shape_2': lambda: _thesis('thesis_shape_2', _BOOMERANG),
    'thesis_shape_3': lambda: _thesis('thesis_shape_3', _RING_OUTER, (_RING_HOLE,)),
    'thesis_shape_4': lambda: _thesis('thesis_shape_4', _star()),
    'thesis_workspace': lambda: shape_from_rings(
        _circle(THESIS_AREA), (), [np.asarray(o.exterior.coords) for o in builtin_obstacles()],
        name='thesis_workspace'),
    'hw_trapezoid': lambda: _plain('hw_trapezoid', _scale_to_area(
        np.array([[-0.6, -0.3], [0.6, -0.3], [0.3, 0.3], [-0.3, 0.3]]), _HW_AREA)[0]),
    'hw_square': lambda: _plain('hw_square', _rect(0.8, 0.8)),
    'hw_pentagon': lambda: _plain('hw_pentagon', _scale_to_area(
        _regular(5, 1.0, np.pi / 2), _HW_AREA)[0]),
    'hw_arrow': lambda: _plain('hw_arrow', _scale_to_area(np.array(
        [[-0.7, -0.15], [0.1, -0.15], [0.1, -0.4], [0.7, 0.0], [0.1, 0.4], [0.1, 0.15],
         [-0.7, 0.15]]), _HW_AREA)[0]),
    'hw_line': lambda: _plain('hw_line', _rect(1.8, 0.36)),
}
