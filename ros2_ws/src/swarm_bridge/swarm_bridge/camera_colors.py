"""Colour calibration of the overhead camera (thesis 5.1, Figs. 5.2-5.4): what the camera
sees of the covers under the arena's light.

The tracker (:mod:`swarm_bridge.camera_tracker`) classifies a robot by the hue of its
cover's circles. A real camera's white balance and the light's colour move hues (a
camera balanced for daylight under warm lamps turns pink toward red), so the printed RGB
of the fleet file may miss. With every robot at its known start pose (the fleet file's
x, y, yaw or ``initial_poses``) this module measures, in one frame:

1. the white balance: per-channel gains that make the covers' off-white plates grey
   (median of the plate pixels: the ring between the circles and the rim, the small
   circle's side left out), keeping their mean level;
2. each cover colour: the median RGB, after those gains, of the most saturated blob (the
   large circle) within the cover around the robot's expected centre; robots of one
   colour give the median of their measurements.

Both go into the calibration file (``white_balance``, ``cover_colors``) that the tracker
reads; measured hues closer than ``MIN_HUE_GAP`` cannot be told apart and are refused.

Pure module (numpy, OpenCV; no rclpy).
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import cv2
import numpy as np

from swarm_bridge.arena_calibration import Calibration, CalibrationError
from swarm_bridge.camera_render import CoverGeometry
from swarm_bridge.camera_tracker import hue_of

MIN_HUE_GAP = 8.0          # OpenCV hue units: closer colours cannot be classified apart
GEOMETRY = CoverGeometry()
MIN_SATURATION = 60        # 0-255: a circle paler than this is not a printed colour


def _disc(shape: tuple[int, int], centre: np.ndarray, radius: float) -> np.ndarray:
    mask = np.zeros(shape, np.uint8)
    cv2.circle(mask, (int(round(centre[0] * 16)), int(round(centre[1] * 16))),
               max(1, int(round(radius * 16))), 255, -1, cv2.LINE_8, 4)
    return mask > 0


def _pixel_radius(calibration: Calibration, pixel: np.ndarray, metres: float) -> float:
    return metres / math.sqrt(calibration.area_per_pixel(pixel))


def measure_white_balance(image: np.ndarray, calibration: Calibration,
                          covers: Sequence[tuple[float, float, float, float]],
                          geometry: CoverGeometry = GEOMETRY) -> tuple[float, float, float]:
    """R, G, B gains that make the cover plates grey. ``covers``: (x, y, yaw, radius) of
    each robot's cover in the arena (m, rad CCW)."""
    g = geometry
    samples = []
    for x, y, yaw, R in covers:
        c = calibration.to_pixels(np.array([x, y]))
        s = calibration.to_pixels(np.array([x + g.small_offset * R * math.cos(yaw),
                                            y + g.small_offset * R * math.sin(yaw)]))
        px = _pixel_radius(calibration, c, 1.0)
        ring = (_disc(image.shape[:2], c, 0.85 * R * px)
                & ~_disc(image.shape[:2], c, (g.large_radius + 0.12) * R * px)
                & ~_disc(image.shape[:2], s, (g.small_radius + 0.15) * R * px))
        if ring.sum() >= 10:
            samples.append(image[ring].reshape(-1, 3).astype(float))
    if not samples:
        raise CalibrationError('no cover plate in view at the start poses; place every '
                               'robot at its start pose (fleet file x, y, yaw or --poses)')
    b, g_, r = np.median(np.vstack(samples), axis=0)
    if min(b, g_, r) < 20:
        raise CalibrationError(f'the cover plates are too dark (RGB {r:.0f}, {g_:.0f}, '
                               f'{b:.0f}); light the arena or open the lens')
    mean = (r + g_ + b) / 3.0
    return mean / r, mean / g_, mean / b


def measure_cover_colors(image: np.ndarray, calibration: Calibration,
                         robots: Sequence, poses: Sequence[tuple[float, float, float]],
                         geometry: CoverGeometry = GEOMETRY
                         ) -> tuple[tuple[float, float, float], dict[str, tuple[int, int, int]]]:
    """White balance (R, G, B gains) and the cover colours (name -> RGB after the gains)
    from one frame with ``robots`` (fleet entries: id, color, radius) at ``poses``
    (x m, y m, yaw rad CCW each)."""
    if len(robots) != len(poses):
        raise CalibrationError(f'{len(poses)} start poses for {len(robots)} robots')
    h, w = image.shape[:2]
    if (w, h) != tuple(calibration.size):
        raise CalibrationError(f'a {w}x{h} frame, but the calibration is for '
                               f'{calibration.size[0]}x{calibration.size[1]}: run '
                               'camera_calibrate at this resolution first')
    covers = [(p[0], p[1], p[2], r.radius) for r, p in zip(robots, poses)]
    balance = measure_white_balance(image, calibration, covers, geometry)
    balanced = cv2.transform(image, np.diag(balance[::-1]).astype(np.float32))
    hsv = cv2.cvtColor(balanced, cv2.COLOR_BGR2HSV)
    sat = hsv[..., 1]
    measured: dict[str, list[np.ndarray]] = {}
    for robot, (x, y, _) in zip(robots, poses):
        c = calibration.to_pixels(np.array([x, y]))
        window = _disc(sat.shape, c, 0.9 * _pixel_radius(calibration, c, robot.radius))
        values = sat[window]
        top = float(np.percentile(values, 98)) if values.size else 0.0
        if top < MIN_SATURATION:
            raise CalibrationError(
                f'robot {robot.id} ({robot.color}): no coloured circle within its cover at '
                f'({x:.2f}, {y:.2f}); place it at its start pose (fleet file or --poses), in '
                'full view')
        blob = (window & (sat >= 0.6 * top)).astype(np.uint8)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(blob, connectivity=4)
        largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        inner = cv2.erode((labels == largest).astype(np.uint8), np.ones((3, 3), np.uint8))
        if inner.sum() < 4:
            inner = (labels == largest).astype(np.uint8)
        bgr = np.median(balanced[inner > 0].reshape(-1, 3).astype(float), axis=0)
        measured.setdefault(robot.color, []).append(bgr[::-1])
    colors = {name: tuple(int(round(v)) for v in np.median(np.array(rgbs), axis=0))
              for name, rgbs in sorted(measured.items())}
    hues = {name: hue_of(rgb) for name, rgb in colors.items()}
    names = sorted(hues)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            gap = abs((hues[a] - hues[b] + 90.0) % 180.0 - 90.0)
            if gap < MIN_HUE_GAP:
                raise CalibrationError(
                    f'cover colours {a} and {b} look alike to this camera (hues '
                    f'{hues[a]:.0f} and {hues[b]:.0f} of 180, {gap:.1f} apart; at least '
                    f'{MIN_HUE_GAP:.0f} needed); print one of them in another colour')
    return balance, colors
