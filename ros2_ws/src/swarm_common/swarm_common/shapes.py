"""Formation shapes: one validated ``Shape`` type and one loader (thesis 1.3, 2.2, 3.2.1).

The thesis's formation shapes are simple closed contours without an analytic formula.
Every component (mission, agents, simulator, metrics) uses the ``Shape`` defined here:
a shapely polygon (outer ring with optional holes) that is valid, non-empty and finite,
plus optional workspace obstacles (polygons that may lie outside the formation).

``load_shape(spec)`` accepts

- a built-in name (see :mod:`swarm_common.builtin_shapes`, ``builtin_shape_names()``);
- ``*.json``: ``{"outer": [[x, y], ...], "holes": [[[x, y], ...], ...],
  "obstacles": [[[x, y], ...], ...]}`` in metres (holes and obstacles optional; a ring
  may repeat its first vertex at the end or not);
- ``*.svg``: the first closed path (or polygon) of the drawing, ``scale`` metres per
  SVG unit, y pointing up; further closed sub-paths of that path inside it are holes;
- ``*.png``: the largest dark region (luminance < 128, opaque) as a silhouette,
  ``metres_per_pixel`` per pixel; enclosed light areas are holes.

Every bad input raises :class:`ShapeError` naming the problem and the fix.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import json
import pathlib
import re
import xml.etree.ElementTree as ET

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient
from shapely.validation import explain_validity


class ShapeError(ValueError):
    """A formation shape that cannot be used; the message names the problem and the fix."""


@dataclass(frozen=True)
class Shape:
    """A validated formation shape (region with holes) and workspace obstacles."""

    name: str
    region: Polygon
    obstacles: tuple[Polygon, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.region, Polygon) or self.region.is_empty:
            raise ShapeError(f'shape {self.name!r}: region must be a non-empty Polygon')
        if not self.region.is_valid:
            raise ShapeError(f'shape {self.name!r} is invalid: '
                             f'{explain_validity(self.region)}; fix the outline')
        object.__setattr__(self, 'obstacles', tuple(self.obstacles))
        # Every robot asks whether its estimate is inside at each heartbeat and outer
        # tick (eq. 4.1), the evaluator for the whole swarm: a prepared region answers
        # the same, a third faster for a point (2.1 against 3.2 us, the thesis circle).
        shapely.prepare(self.region)

    @property
    def area(self) -> float:
        """Area of the region (holes excluded), m^2."""
        return float(self.region.area)

    @property
    def boundary_length(self) -> float:
        """Total length of all rings (outer and holes), m."""
        return float(self.region.length)

    @property
    def centroid(self) -> np.ndarray:
        """Area centroid (not the eq. 3.66 boundary-sample mean), shape (2,)."""
        c = self.region.centroid
        return np.array([c.x, c.y])

    def translated(self, dx: float, dy: float) -> Shape:
        """The same shape moved by (dx, dy) metres (obstacles move with it)."""
        from shapely import affinity
        return Shape(self.name, affinity.translate(self.region, dx, dy),
                     tuple(affinity.translate(o, dx, dy) for o in self.obstacles))

    def inset(self, margin: float) -> Shape:
        """The region shrunk by ``margin`` metres along every ring (obstacles unchanged).

        A safety band inside the contour: goals placed in the inset shape keep a robot
        that parks up to ``margin`` from its goal inside the shape. Raises ShapeError when
        nothing is left or the shape splits (a neck narrower than 2 ``margin``).
        """
        if not (np.isfinite(margin) and margin >= 0):
            raise ShapeError(f'inset margin must be a finite number >= 0 m, got {margin!r}')
        if margin == 0:
            return self
        region = self.region.buffer(-float(margin))
        if region.is_empty or region.area <= 0:
            raise ShapeError(f'shape {self.name!r} vanishes when shrunk by {margin:g} m; '
                             'use a smaller margin or a larger shape')
        if not isinstance(region, Polygon):
            raise ShapeError(f'shape {self.name!r} splits into {len(region.geoms)} parts when '
                             f'shrunk by {margin:g} m (a neck narrower than {2 * margin:g} '
                             'm); use a smaller margin')
        return Shape(self.name, region, self.obstacles)

    def scaled(self, factor: float) -> Shape:
        """The shape scaled by ``factor`` about the origin (obstacles too)."""
        if not (np.isfinite(factor) and factor > 0):
            raise ShapeError(f'scale must be a positive finite number, got {factor!r}')
        from shapely import affinity
        return Shape(self.name, affinity.scale(self.region, factor, factor, origin=(0, 0)),
                     tuple(affinity.scale(o, factor, factor, origin=(0, 0))
                           for o in self.obstacles))


def _ring(coords, what: str) -> np.ndarray:
    """A ring as an (k, 2) finite array without the repeated closing vertex."""
    try:
        arr = np.asarray(coords, dtype=float)
    except (TypeError, ValueError):
        raise ShapeError(f'{what} is not a list of [x, y] pairs; write [[x, y], ...]') from None
    if arr.size == 0:
        raise ShapeError(f'{what} is empty; give at least 3 [x, y] vertices')
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ShapeError(f'{what} must be a list of [x, y] pairs, got array of shape '
                         f'{arr.shape}')
    if not np.isfinite(arr).all():
        raise ShapeError(f'{what} contains NaN or infinite coordinates; give finite metres')
    if len(arr) > 1 and np.array_equal(arr[0], arr[-1]):
        arr = arr[:-1]
    if len(np.unique(arr, axis=0)) < 3:
        raise ShapeError(f'{what} has fewer than 3 distinct vertices; a ring needs 3 or more')
    return arr


def _simple_polygon(arr: np.ndarray, what: str) -> Polygon:
    poly = Polygon(arr)
    if np.linalg.matrix_rank(arr - arr.mean(axis=0), tol=1e-12) < 2:
        raise ShapeError(f'{what} encloses no area (collinear vertices); give a '
                         'non-degenerate ring')
    if not poly.is_valid:
        raise ShapeError(f'{what} is not a simple closed ring ({explain_validity(poly)}); '
                         'remove the self-intersection')
    return poly


def shape_from_rings(outer, holes: Iterable = (), obstacles: Iterable = (),
                     name: str = '') -> Shape:
    """Build and validate a Shape from rings given as (k, 2) arrays or [[x, y], ...] lists.

    The closing vertex is optional. Raises ShapeError for empty, NaN, self-intersecting
    or zero-area rings, holes not inside the outer ring and holes that overlap.
    """
    name = name or 'shape'
    outer_arr = _ring(outer, f'shape {name!r}: outer ring')
    outer_poly = _simple_polygon(outer_arr, f'shape {name!r}: outer ring')
    hole_arrs = []
    for i, hole in enumerate(holes):
        arr = _ring(hole, f'shape {name!r}: hole {i}')
        hole_poly = _simple_polygon(arr, f'shape {name!r}: hole {i}')
        if not outer_poly.contains(hole_poly):
            raise ShapeError(f'shape {name!r}: hole {i} lies (partly) outside the outer ring; '
                             'holes must be strictly inside it')
        hole_arrs.append(arr)
    region = Polygon(outer_arr, hole_arrs)
    if not region.is_valid:
        raise ShapeError(f'shape {name!r}: holes overlap or touch each other '
                         f'({explain_validity(region)}); merge or separate them')
    obstacle_polys = []
    for i, obstacle in enumerate(obstacles):
        arr = _ring(obstacle, f'shape {name!r}: obstacle {i}')
        obstacle_polys.append(orient(_simple_polygon(arr, f'shape {name!r}: obstacle {i}')))
    return Shape(name, orient(region, sign=1.0), tuple(obstacle_polys))


def shape_from_polygon(polygon: Polygon, obstacles: Sequence[Polygon] = (),
                       name: str = '') -> Shape:
    """Validate a shapely Polygon (with holes) as a Shape."""
    if not isinstance(polygon, Polygon) or polygon.is_empty:
        raise ShapeError(f'shape {name!r} must be a single non-empty polygon, got '
                         f'{type(polygon).__name__}')
    return shape_from_rings(np.asarray(polygon.exterior.coords),
                            [np.asarray(h.coords) for h in polygon.interiors],
                            [np.asarray(o.exterior.coords) for o in obstacles], name=name)


# ---------------------------------------------------------------- JSON

def shape_json(shape: Shape) -> dict:
    """The ``*.json`` layout of ``shape`` (outer, holes, obstacles in metres); read back by
    ``shape_from_json`` into the same rings."""
    def ring(coords) -> list[list[float]]:
        return [[float(x), float(y)] for x, y in list(coords)[:-1]]

    return {'outer': ring(shape.region.exterior.coords),
            'holes': [ring(h.coords) for h in shape.region.interiors],
            'obstacles': [ring(o.exterior.coords) for o in shape.obstacles]}


def shape_from_json(data, name: str, where: str) -> Shape:
    """The shape of a decoded ``*.json`` layout; ShapeError names ``where`` it came from."""
    if not isinstance(data, dict) or 'outer' not in data:
        raise ShapeError(f'{where} needs an object with an "outer" ring: '
                         '{"outer": [[x, y], ...], "holes": [...], "obstacles": [...]}')
    return shape_from_rings(data['outer'], data.get('holes') or (),
                            data.get('obstacles') or (), name=name)


def _load_json(path: pathlib.Path) -> Shape:
    try:
        data = json.loads(path.read_text(encoding='utf-8'))
    except OSError as exc:
        raise ShapeError(f'cannot read shape file {path}: {exc.strerror}') from None
    except ValueError as exc:
        raise ShapeError(f'shape file {path} is not valid JSON: {exc}') from None
    return shape_from_json(data, path.stem, f'shape file {path}')


# ---------------------------------------------------------------- SVG

_SVG_NUMBER = r'[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?'
_SVG_TOKEN = re.compile(r'[MmLlHhVvCcSsQqTtAaZz]|' + _SVG_NUMBER)
_SVG_ARGS = {'M': 2, 'L': 2, 'H': 1, 'V': 1, 'C': 6, 'S': 4, 'Q': 4, 'T': 2, 'A': 7, 'Z': 0}
_CURVE_SAMPLES = 16


def _bezier(points: np.ndarray) -> np.ndarray:
    """Samples (without the start point) of a quadratic or cubic Bezier segment."""
    t = np.linspace(0.0, 1.0, _CURVE_SAMPLES + 1)[1:, None]
    if len(points) == 3:
        return (1 - t) ** 2 * points[0] + 2 * (1 - t) * t * points[1] + t ** 2 * points[2]
    return ((1 - t) ** 3 * points[0] + 3 * (1 - t) ** 2 * t * points[1]
            + 3 * (1 - t) * t ** 2 * points[2] + t ** 3 * points[3])


def _svg_subpaths(d: str) -> list[tuple[np.ndarray, bool]]:
    """Parse an SVG path ``d`` into (vertices, closed) sub-paths.

    Lines and Bezier curves are supported (curves sampled); an elliptical arc is
    replaced by its chord.
    """
    tokens = _SVG_TOKEN.findall(d)
    subpaths: list[tuple[np.ndarray, bool]] = []
    current: list[np.ndarray] = []
    pos = np.zeros(2)
    start = np.zeros(2)
    last_ctrl = None
    cmd = None
    i = 0

    def flush(closed: bool) -> None:
        if current:
            subpaths.append((np.array(current), closed))
        current.clear()

    while i < len(tokens):
        if tokens[i].isalpha():
            cmd = tokens[i]
            i += 1
            if cmd in 'Zz':
                flush(True)
                pos = start.copy()
                last_ctrl = None
                continue
        if cmd is None:
            raise ShapeError('SVG path data must start with a command letter (M)')
        n = _SVG_ARGS[cmd.upper()]
        try:
            args = np.array([float(v) for v in tokens[i:i + n]])
        except ValueError:
            raise ShapeError(f'SVG path command {cmd} has malformed arguments') from None
        if len(args) < n:
            raise ShapeError(f'SVG path command {cmd} needs {n} numbers')
        i += n
        rel = cmd.islower()
        up = cmd.upper()
        base = pos if rel else np.zeros(2)
        ctrl = None
        if up == 'M':
            flush(False)
            pos = base + args
            start = pos.copy()
            current.append(pos.copy())
            cmd = 'l' if rel else 'L'
        elif up == 'L':
            pos = base + args
            current.append(pos.copy())
        elif up == 'H':
            pos = np.array([(pos[0] if rel else 0.0) + args[0], pos[1]])
            current.append(pos.copy())
        elif up == 'V':
            pos = np.array([pos[0], (pos[1] if rel else 0.0) + args[0]])
            current.append(pos.copy())
        elif up == 'A':
            pos = base + args[5:7]
            current.append(pos.copy())
        else:
            pts = args.reshape(-1, 2) + base
            if up in 'ST':
                reflected = 2 * pos - last_ctrl if last_ctrl is not None else pos.copy()
                pts = np.vstack([reflected, pts])
            ctrl = pts[-2]
            current.extend(_bezier(np.vstack([pos, pts])))
            pos = pts[-1]
        last_ctrl = ctrl
    flush(False)
    return subpaths


def _load_svg(path: pathlib.Path) -> Shape:
    try:
        root = ET.parse(path).getroot()
    except OSError as exc:
        raise ShapeError(f'cannot read SVG file {path}: {exc.strerror}') from None
    except ET.ParseError as exc:
        raise ShapeError(f'{path} is not a readable SVG (XML error: {exc}); '
                         'export a plain SVG') from None
    for element in root.iter():
        tag = element.tag.rsplit('}', 1)[-1]
        if tag == 'path':
            subpaths = _svg_subpaths(element.get('d', ''))
            closed = [p for p, c in subpaths if c or (len(p) > 2 and np.allclose(p[0], p[-1]))]
            if not closed:
                continue
        elif tag == 'polygon':
            nums = [float(v) for v in re.findall(_SVG_NUMBER, element.get('points', ''))]
            closed = [np.array(nums[:len(nums) // 2 * 2]).reshape(-1, 2)]
        else:
            continue
        rings = [np.column_stack([p[:, 0], -p[:, 1]]) for p in closed]
        outer = _ring(rings[0], f'SVG {path.name}: first closed path')
        outer_poly = _simple_polygon(outer, f'SVG {path.name}: first closed path')
        holes = [r for r in rings[1:] if outer_poly.contains(Polygon(r).buffer(0))]
        return shape_from_rings(outer, holes, name=path.stem)
    raise ShapeError(f'SVG {path} has no closed path or polygon; close the outline with Z')


# ---------------------------------------------------------------- PNG

def _load_png(path: pathlib.Path, metres_per_pixel: float) -> Shape:
    import contourpy
    from PIL import Image, UnidentifiedImageError
    from scipy import ndimage
    try:
        with Image.open(path) as image:
            rgba = np.asarray(image.convert('RGBA'), dtype=float)
    except UnidentifiedImageError:
        raise ShapeError(f'{path} is not a readable image; give a PNG silhouette') from None
    except OSError as exc:
        raise ShapeError(f'cannot read image {path}: {exc}; give a PNG silhouette') from None
    luminance = rgba[..., :3] @ np.array([0.299, 0.587, 0.114])
    dark = (luminance < 128.0) & (rgba[..., 3] > 127.0)
    labels, count = ndimage.label(dark)
    if count == 0:
        raise ShapeError(f'image {path} has no dark region; draw the shape in black on white')
    sizes = np.bincount(labels.ravel())[1:]
    mask = np.pad(labels == 1 + int(np.argmax(sizes)), 1).astype(float)
    lines = contourpy.contour_generator(z=mask).lines(0.5)
    polys = sorted((Polygon(line) for line in lines if len(line) >= 4),
                   key=lambda p: p.area, reverse=True)
    if not polys:
        raise ShapeError(f'image {path}: the dark region is too small to outline')
    outer = polys[0]
    holes = [p for p in polys[1:] if outer.contains(p)]
    region = Polygon(outer.exterior.coords, [h.exterior.coords for h in holes]).simplify(0.5)
    region = shapely.affinity.scale(region, metres_per_pixel, -metres_per_pixel, origin=(0, 0))
    return shape_from_polygon(region, name=path.stem)


# ---------------------------------------------------------------- loader

def builtin_shape_names() -> list[str]:
    """Names accepted by :func:`load_shape` besides file paths."""
    from swarm_common.builtin_shapes import BUILTIN_SHAPES
    return sorted(BUILTIN_SHAPES)


def load_shape(spec: str, *, scale: float = 1.0, metres_per_pixel: float = 0.05,
               center: bool | None = None) -> Shape:
    """Load a shape from a built-in name or a .json/.svg/.png file.

    ``scale`` multiplies the result (for SVG it is metres per SVG unit);
    ``metres_per_pixel`` sizes PNG silhouettes. ``center`` moves the area centroid to
    the origin (obstacles move along); by default SVG and PNG shapes, which come in
    drawing coordinates, are centred and built-in and JSON shapes are kept where they are.
    """
    if not (isinstance(scale, (int, float)) and np.isfinite(scale) and scale > 0):
        raise ShapeError(f'shape scale must be a positive number, got {scale!r}')
    if not (np.isfinite(metres_per_pixel) and metres_per_pixel > 0):
        raise ShapeError(f'metres_per_pixel must be positive, got {metres_per_pixel!r}')
    from swarm_common.builtin_shapes import BUILTIN_SHAPES
    spec = str(spec)
    path = pathlib.Path(spec)
    suffix = path.suffix.lower()
    if spec in BUILTIN_SHAPES:
        shape = BUILTIN_SHAPES[spec]()
        default_center = False
    elif suffix in ('.json', '.svg', '.png'):
        if not path.is_file():
            raise ShapeError(f'shape file {spec} does not exist; give an existing path or one '
                             f'of the built-in names {builtin_shape_names()}')
        if suffix == '.json':
            shape, default_center = _load_json(path), False
        elif suffix == '.svg':
            shape, default_center = _load_svg(path), True
        else:
            shape, default_center = _load_png(path, metres_per_pixel), True
    else:
        raise ShapeError(f'unknown shape {spec!r}: give a .json, .svg or .png file or one of '
                         f'the built-in names {builtin_shape_names()}')
    if center if center is not None else default_center:
        c = shape.centroid
        shape = shape.translated(-c[0], -c[1])
    return shape.scaled(scale) if scale != 1.0 else shape
