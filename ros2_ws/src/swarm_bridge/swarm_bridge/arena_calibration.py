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
class Calibration:
    """Pixel -> arena homography ``H`` (3x3) for images of ``size`` (width, height)."""

    H: np.ndarray
    size: tuple[int, int]
    rms_m: float = 0.0
    markers: ArenaMarkers = field(default_factory=ArenaMarkers)

    def __post_init__(self) -> None:
        self.H = np.asarray(self.H, dtype=float).reshape(3, 3)
        self.H_inv = np.linalg.inv(self.H)

    def to_arena(self, pixels: np.ndarray) -> np.ndarray:
        """Map pixel coordinates (..., 2) (u right, v down) to arena metres (..., 2)."""
        return apply_homography(self.H, pixels)

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """Map arena metres (..., 2) to pixel coordinates (..., 2)."""
        return apply_homography(self.H_inv, points)

    def area_per_pixel(self, pixel: np.ndarray) -> float:
        """Arena area (m^2) of one pixel at ``pixel``: the homography's Jacobian there."""
        return abs(float(np.linalg.det(homography_jacobian(self.H, pixel))))

    def save(self, path: str | pathlib.Path) -> None:
        """Write the calibration as YAML (what the tracker's ``calibration_file`` reads)."""
        doc = {'homography_pixel_to_arena': [[float(v) for v in row] for row in self.H],
               'image_size': [int(self.size[0]), int(self.size[1])],
               'rms_error_m': float(self.rms_m),
               'markers': {'ids': list(self.markers.ids),
                           'centres': [list(c) for c in self.markers.centres],
                           'side': self.markers.side}}
        pathlib.Path(path).write_text(
            '# Overhead camera calibration (swarm_bridge camera_calibrate): pixel -> arena\n'
            + yaml.safe_dump(doc, sort_keys=False))

    @classmethod
    def load(cls, path: str | pathlib.Path) -> Calibration:
        """Read a calibration YAML written by :meth:`save`."""
        try:
            doc = yaml.safe_load(pathlib.Path(path).read_text())
            m = doc.get('markers', {})
            markers = ArenaMarkers(tuple(m['ids']), tuple(tuple(c) for c in m['centres']),
                                   float(m['side'])) if m else ArenaMarkers()
            return cls(np.array(doc['homography_pixel_to_arena'], dtype=float),
                       tuple(doc['image_size']), float(doc.get('rms_error_m', 0.0)), markers)
        except OSError as exc:
            raise CalibrationError(f'cannot read calibration file {path}: {exc.strerror}; '
                                   'run camera_calibrate first') from None
        except (KeyError, TypeError, ValueError, AttributeError, np.linalg.LinAlgError):
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


def calibrate(image: np.ndarray, markers: ArenaMarkers = ArenaMarkers()) -> Calibration:
    """Fit the pixel -> arena homography to the four corner markers seen in ``image``."""
    found = find_markers(image)
    missing = [i for i in markers.ids if i not in found]
    if missing:
        raise CalibrationError(
            f'corner markers {missing} not found in the image (found {sorted(found)}); '
            f'place ArUco 4x4_50 markers {list(markers.ids)} at the arena corners, '
            f'upright, in full view and evenly lit')
    pixels = np.vstack([found[i] for i in markers.ids])
    arena = np.vstack([markers.corners(i) for i in markers.ids])
    H, _ = cv2.findHomography(pixels, arena, 0)
    if H is None:
        raise CalibrationError('the corner markers are degenerate (collinear?); '
                               'place them at the four corners of the arena')
    residual = apply_homography(H, pixels) - arena
    rms = float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))
    h, w = image.shape[:2]
    return Calibration(H, (w, h), rms, markers)
