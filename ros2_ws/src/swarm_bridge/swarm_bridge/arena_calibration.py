"""The overhead camera's calibration: a homography from image pixels to the arena (ch. 5.1).

Thesis 5.1 (Figs. 5.1-5.4) finds the robots in the image of an E/O camera above the
2 x 2 m arena. Pixels become metres through a plane homography fitted to four ArUco
markers (OpenCV dictionary 4x4_50, ids 0-3) lying at the arena's corners, in the plane
of the robots' covers. Each marker lies upright: its top edge toward +y of the arena
(REP 103 map frame: x right, y up seen from above), so its four detected corners (top
left, top right, bottom right, bottom left) have known arena coordinates; the 16 corners
give a least-squares homography.

Pure module (numpy, OpenCV, yaml; no rclpy).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import pathlib

import cv2
import numpy as np
import yaml

ARUCO_DICTIONARY = cv2.aruco.DICT_4X4_50


LENS_ITERATIONS = 20     # fixed-point steps of the radial undistortion (converged to 1e-9)


class CalibrationError(ValueError):
    """A calibration that cannot be made or read; the message names the input and the fix."""


@dataclass(frozen=True)
class ArenaMarkers:
    """The four corner markers: ArUco ids and centres (m, map frame), side length (m)."""

    ids: tuple[int, ...] = (0, 1, 2, 3)
    centres: tuple[tuple[float, float], ...] = ((-1.08, -1.08), (1.08, -1.08),
                                                (1.08, 1.08), (-1.08, 1.08))
    side: float = 0.12

    def corners(self, marker_id: int) -> np.ndarray:
        """Arena coordinates (4, 2) of a marker's corners in ArUco order (TL, TR, BR, BL)."""
        cx, cy = self.centres[self.ids.index(marker_id)]
        h = self.side / 2.0
        return np.array([[cx - h, cy + h], [cx + h, cy + h], [cx + h, cy - h],
                         [cx - h, cy - h]])


@dataclass
class Lens:
    """Radial lens distortion (OpenCV's model, no tangential terms): camera matrix ``K``
    (3x3: focal lengths and principal point, pixels) and ``k1``, ``k2``. A pixel of the
    ideal (pinhole) image at normalized radius r appears at r (1 + k1 r^2 + k2 r^4)."""

    K: np.ndarray
    k1: float
    k2: float
    rms_px: float = 0.0

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, dtype=float).reshape(3, 3)

    @property
    def coefficients(self) -> np.ndarray:
        """OpenCV distortion coefficients (k1, k2, p1, p2)."""
        return np.array([self.k1, self.k2, 0.0, 0.0])

    def _normalize(self, pixels: np.ndarray) -> np.ndarray:
        K = self.K
        return (pixels - K[:2, 2]) / np.array([K[0, 0], K[1, 1]])

    def _pixels(self, normalized: np.ndarray) -> np.ndarray:
        K = self.K
        return normalized * np.array([K[0, 0], K[1, 1]]) + K[:2, 2]

    def distort(self, pixels: np.ndarray) -> np.ndarray:
        """Ideal pixel coordinates (..., 2) -> where the lens puts them (..., 2)."""
        n = self._normalize(np.asarray(pixels, dtype=float))
        r2 = np.sum(n * n, axis=-1, keepdims=True)
        return self._pixels(n * (1.0 + self.k1 * r2 + self.k2 * r2 * r2))

    def undistort(self, pixels: np.ndarray) -> np.ndarray:
        """Distorted pixel coordinates (..., 2) -> ideal (pinhole) ones (..., 2), by
        fixed-point iteration of the radial model (what cv2.undistortPoints does, for
        arrays of any shape; a single point in plain floats, the tracker's case)."""
        pixels = np.asarray(pixels, dtype=float)
        if pixels.shape == (2,):
            fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
            dx, dy = (float(pixels[0]) - cx) / fx, (float(pixels[1]) - cy) / fy
            x, y = dx, dy
            for _ in range(LENS_ITERATIONS):
                r2 = x * x + y * y
                f = 1.0 + self.k1 * r2 + self.k2 * r2 * r2
                x, y = dx / f, dy / f
            return np.array([x * fx + cx, y * fy + cy])
        d = self._normalize(pixels)
        n = d.copy()
        for _ in range(LENS_ITERATIONS):
            r2 = np.sum(n * n, axis=-1, keepdims=True)
            n = d / (1.0 + self.k1 * r2 + self.k2 * r2 * r2)
        return self._pixels(n)

    def area_factor(self, ideal: np.ndarray) -> float:
        """Area of one distorted pixel in ideal pixels at the ideal pixel ``ideal``: the
        inverse of the distortion's Jacobian determinant, f (f + 2 r^2 f') for the radial
        factor f(r^2) = 1 + k1 r^2 + k2 r^4."""
        n = self._normalize(np.asarray(ideal, dtype=float))
        r2 = float(n[0] * n[0] + n[1] * n[1])
        f = 1.0 + self.k1 * r2 + self.k2 * r2 * r2
        df = self.k1 + 2.0 * self.k2 * r2
        return 1.0 / abs(f * (f + 2.0 * r2 * df))


@dataclass
class Calibration:
    """Pixel -> arena homography ``H`` (3x3) for images of ``size`` (width, height), fitted
    to ideal (undistorted) pixels when a ``lens`` is known; optionally the colours the
    camera sees: channel gains that make the white cover plates neutral
    (``white_balance``, R, G, B) and each cover colour's RGB after them
    (``cover_colors``), both measured by ``camera_calibrate --colors``."""

    H: np.ndarray
    size: tuple[int, int]
    rms_m: float = 0.0
    markers: ArenaMarkers = field(default_factory=ArenaMarkers)
    lens: Lens | None = None
    white_balance: tuple[float, float, float] | None = None
    cover_colors: dict[str, tuple[int, int, int]] | None = None

    def __post_init__(self) -> None:
        self.H = np.asarray(self.H, dtype=float).reshape(3, 3)
        self.H_inv = np.linalg.inv(self.H)

    def undistort(self, pixels: np.ndarray) -> np.ndarray:
        """Image pixels (..., 2) -> ideal pixels (the same without a lens)."""
        return pixels if self.lens is None else self.lens.undistort(pixels)

    def to_arena(self, pixels: np.ndarray) -> np.ndarray:
        """Map pixel coordinates (..., 2) (u right, v down) to arena metres (..., 2)."""
        return apply_homography(self.H, self.undistort(np.asarray(pixels, dtype=float)))

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """Map arena metres (..., 2) to pixel coordinates (..., 2)."""
        ideal = apply_homography(self.H_inv, points)
        return ideal if self.lens is None else self.lens.distort(ideal)

    def area_per_pixel(self, pixel: np.ndarray) -> float:
        """Arena area (m^2) of one pixel at ``pixel``: the Jacobian of the homography
        (and of the undistortion) there."""
        ideal = self.undistort(np.asarray(pixel, dtype=float))
        area = abs(float(np.linalg.det(homography_jacobian(self.H, ideal))))
        return area if self.lens is None else area * self.lens.area_factor(ideal)

    def save(self, path: str | pathlib.Path) -> None:
        """Write the calibration as YAML (what the tracker's ``calibration_file`` reads)."""
        doc = {'homography_pixel_to_arena': [[float(v) for v in row] for row in self.H],
               'image_size': [int(self.size[0]), int(self.size[1])],
               'rms_error_m': float(self.rms_m),
               'markers': {'ids': list(self.markers.ids),
                           'centres': [list(c) for c in self.markers.centres],
                           'side': self.markers.side}}
        if self.lens is not None:
            doc['lens'] = {'camera_matrix': [[float(v) for v in row] for row in self.lens.K],
                           'k1': float(self.lens.k1), 'k2': float(self.lens.k2),
                           'rms_error_px': float(self.lens.rms_px)}
        if self.white_balance is not None:
            doc['white_balance'] = [round(float(g), 4) for g in self.white_balance]
        if self.cover_colors is not None:
            doc['cover_colors'] = {name: [int(v) for v in rgb]
                                   for name, rgb in self.cover_colors.items()}
        pathlib.Path(path).write_text(
            '# Overhead camera calibration (swarm_bridge camera_calibrate): pixel -> arena\n'
            + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))

    @classmethod
    def load(cls, path: str | pathlib.Path, *, need_arena: bool = True) -> Calibration:
        """Read a calibration YAML written by :meth:`save`; without ``need_arena`` a file
        holding only a lens (``camera_calibrate --lens``) is read too (identity H)."""
        try:
            doc = yaml.safe_load(pathlib.Path(path).read_text())
            if not isinstance(doc, dict):
                raise TypeError
            lens = doc.get('lens')
            if lens is not None:
                lens = Lens(np.array(lens['camera_matrix'], dtype=float), float(lens['k1']),
                            float(lens['k2']), float(lens.get('rms_error_px', 0.0)))
            if 'homography_pixel_to_arena' not in doc and not need_arena and lens:
                return cls(np.eye(3), tuple(doc['image_size']), lens=lens)
            m = doc.get('markers', {})
            markers = ArenaMarkers(tuple(m['ids']), tuple(tuple(c) for c in m['centres']),
                                   float(m['side'])) if m else ArenaMarkers()
            balance = doc.get('white_balance')
            if balance is not None:
                balance = tuple(float(g) for g in balance)
                if len(balance) != 3 or not all(0.1 < g < 10.0 for g in balance):
                    raise ValueError
            colors = doc.get('cover_colors')
            if colors is not None:
                colors = {str(k): tuple(int(v) for v in rgb) for k, rgb in colors.items()}
                if not all(len(rgb) == 3 and all(0 <= v <= 255 for v in rgb)
                           for rgb in colors.values()):
                    raise ValueError
            size = tuple(int(v) for v in doc['image_size'])
            if len(size) != 2:
                raise ValueError
            return cls(np.array(doc['homography_pixel_to_arena'], dtype=float), size,
                       float(doc.get('rms_error_m', 0.0)), markers, lens, balance, colors)
        except OSError as exc:
            raise CalibrationError(f'cannot read calibration file {path}: {exc.strerror}; '
                                   'run camera_calibrate first') from None
        except (KeyError, TypeError, ValueError, AttributeError, IndexError,
                np.linalg.LinAlgError, yaml.YAMLError):
            raise CalibrationError(f'{path} is not a calibration file written by '
                                   'camera_calibrate; run it again') from None


def apply_homography(H: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 3x3 homography to points (..., 2)."""
    pts = np.asarray(points, dtype=float)
    flat = pts.reshape(-1, 2)
    w = flat @ H[:2, :2].T + H[:2, 2]
    z = flat @ H[2, :2] + H[2, 2]
    return (w / z[:, None]).reshape(pts.shape)


def homography_jacobian(H: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The 2x2 Jacobian of the homography's map at ``point``."""
    u, v = float(point[0]), float(point[1])
    z = H[2, 0] * u + H[2, 1] * v + H[2, 2]
    x = (H[0, 0] * u + H[0, 1] * v + H[0, 2]) / z
    y = (H[1, 0] * u + H[1, 1] * v + H[1, 2]) / z
    return np.array([[H[0, 0] - x * H[2, 0], H[0, 1] - x * H[2, 1]],
                     [H[1, 0] - y * H[2, 0], H[1, 1] - y * H[2, 1]]]) / z


def marker_detector() -> cv2.aruco.ArucoDetector:
    """An ArUco detector for the corner markers, with sub-pixel corner refinement."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARY), params)


def find_markers(image: np.ndarray) -> dict[int, np.ndarray]:
    """Detected ArUco markers: id -> corner pixels (4, 2) in ArUco order."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    corners, ids, _ = marker_detector().detectMarkers(gray)
    if ids is None:
        return {}
    return {int(i): c.reshape(4, 2).astype(float) for i, c in zip(ids.ravel(), corners)}


def calibrate(image: np.ndarray, markers: ArenaMarkers = ArenaMarkers(),
              lens: Lens | None = None) -> Calibration:
    """Fit the pixel -> arena homography to the four corner markers seen in ``image``
    (their corners undistorted first when the ``lens`` is known)."""
    found = find_markers(image)
    missing = [i for i in markers.ids if i not in found]
    if missing:
        raise CalibrationError(
            f'corner markers {missing} not found in the image (found {sorted(found)}); '
            f'place ArUco 4x4_50 markers {list(markers.ids)} at the arena corners, '
            f'upright, in full view and evenly lit')
    pixels = np.vstack([found[i] for i in markers.ids])
    if lens is not None:
        pixels = lens.undistort(pixels)
    arena = np.vstack([markers.corners(i) for i in markers.ids])
    H, _ = cv2.findHomography(pixels, arena, 0)
    if H is None:
        raise CalibrationError('the corner markers are degenerate (collinear?); '
                               'place them at the four corners of the arena')
    residual = apply_homography(H, pixels) - arena
    rms = float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))
    h, w = image.shape[:2]
    return Calibration(H, (w, h), rms, markers, lens)


def find_checkerboard(image: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """The inner corners (N, 2) of a checkerboard of ``pattern`` (columns, rows of inner
    corners) in ``image``, refined to sub-pixel; None if it is not all in view."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    ok, corners = cv2.findChessboardCorners(
        gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        return None
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), (
        cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 40, 0.01))
    return corners.reshape(-1, 2).astype(float)


def calibrate_lens(views: list[np.ndarray], size: tuple[int, int],
                   pattern: tuple[int, int] = (9, 6), square: float = 0.03) -> Lens:
    """The lens (camera matrix, k1, k2) from checkerboard corners seen in ``views`` (each
    (N, 2) of :func:`find_checkerboard`) by Zhang's method (cv2.calibrateCamera; no
    tangential distortion, no k3): the board held at several tilts and places, covering
    the image's corners, where distortion is largest."""
    if len(views) < 4:
        raise CalibrationError(f'{len(views)} checkerboard views found; hold the printed '
                               f'{pattern[0]}x{pattern[1]} board tilted at ten or more '
                               'places covering the whole image')
    grid = np.zeros((pattern[0] * pattern[1], 3), np.float32)
    grid[:, :2] = np.mgrid[0:pattern[0], 0:pattern[1]].T.reshape(-1, 2) * square
    flags = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3
    rms, K, dist, _, _ = cv2.calibrateCamera(
        [grid] * len(views), [v.reshape(-1, 1, 2).astype(np.float32) for v in views],
        tuple(size), None, None, flags=flags)
    return Lens(K, float(dist.ravel()[0]), float(dist.ravel()[1]), float(rms))
