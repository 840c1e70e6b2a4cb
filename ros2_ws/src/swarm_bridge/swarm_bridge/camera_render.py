"""A synthetic overhead camera of the arena (thesis 5.1, Figs. 5.2-5.4), from true poses.

The thesis finds its five robots with an E/O camera above the 2 x 2 m arena: every robot
carries a cover the size of its coverage circle (Fig. 5.2) with two circles of one
colour, a large one at the robot's centre and a small one toward its heading (Fig. 5.3).
This module draws that scene as the camera would see it, so that the tracker
(:mod:`swarm_bridge.camera_tracker`) can be tested against known truth and the
hardware-in-the-loop world can close its loop through an image:

- a mild perspective (a camera not quite square to the floor, slightly rotated);
- a textured floor, the arena's border line and the four ArUco corner markers that
  :mod:`swarm_bridge.arena_calibration` fits its homography to;
- covers drawn lowest first (the largest robot's cover is the highest and hides the edge
  of a smaller neighbour's);
- a lighting gradient across the image and an overall brightness, a white balance (gains
  per colour channel: a camera balanced for another light than the arena's), radial lens
  distortion (``k1``, ``k2`` of OpenCV's model about the image centre, focal length
  ``focal_px``: a wide-angle lens), lens blur (Gaussian) and sensor noise (Gaussian, in
  8-bit digital numbers);
- :meth:`CameraRenderer.checkerboard`: a printed checkerboard held in front of the same lens, the
  views :func:`~swarm_bridge.arena_calibration.calibrate_lens` estimates the distortion
  from;
- :class:`SimCamera`: a frame rate and a latency between capture and delivery.

Pure module (numpy, OpenCV; no rclpy). Images are BGR uint8, as OpenCV and
``sensor_msgs/Image`` encoding ``bgr8`` hold them.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
import math

import cv2
import numpy as np

from swarm_bridge.arena_calibration import apply_homography, ArenaMarkers, ARUCO_DICTIONARY, Lens

PLATE_RGB = (232, 232, 226)     # the cover plate: off-white card
RIM_RGB = (90, 90, 90)          # its edge
FLOOR_RGB = (150, 144, 136)     # grey-beige floor
BORDER_RGB = (40, 40, 40)       # the arena's border line


@dataclass(frozen=True)
class CoverGeometry:
    """Circles on a cover, as fractions of the cover radius (thesis Fig. 5.2).

    The large circle is centred on the robot (its position); the small one lies
    ``small_offset`` ahead along the robot's heading (body +x).
    """

    large_radius: float = 0.30
    small_radius: float = 0.20
    small_offset: float = 0.70


@dataclass(frozen=True)
class CameraConfig:
    """The synthetic camera: image, view, optics, light, noise and timing."""

    width: int = 640
    height: int = 480
    view_half_m: float = 1.17    # half the arena span across the image height, m
    rotation_deg: float = 1.5    # camera roll about its axis
    tilt: float = 0.04           # perspective: the image's top edge sees this much less
    brightness: float = 1.0      # overall gain (0.3 dim .. 1.3 bright)
    gradient: float = 0.3        # gain falls by this fraction from one corner to the other
    blur_sigma_px: float = 0.9   # lens blur
    noise_std: float = 2.0       # sensor noise, digital numbers (0-255)
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)   # R, G, B gains
    k1: float = 0.0              # radial distortion (OpenCV model; < 0: barrel)
    k2: float = 0.0
    focal_px: float = 600.0      # focal length of the distortion model, pixels
    texture: float = 0.08        # floor texture contrast
    rate_hz: float = 30.0        # frames per second
    latency_s: float = 0.05      # capture to delivery
    seed: int = 0                # floor texture and noise


@dataclass(frozen=True)
class Cover:
    """One robot's cover as the camera sees it: colour (RGB), radius (m), pose (m, rad CCW)."""

    rgb: tuple[int, int, int]
    radius: float
    x: float
    y: float
    yaw: float


# The synthetic camera's settings as ROS parameters (camera_sim_node; config/hil.yaml's
# camera_* values): name -> (default, description).
SIM_CAMERA_PARAMETERS = {
    'camera_rate_hz': (10.0, 'Frames a second (at most: one per tick of true poses)'),
    'camera_latency_s': (0.05, 'Capture to publication, s'),
    'camera_brightness': (1.0, 'Overall light (0.3 dim .. 1.3 bright)'),
    'camera_gradient': (0.3, 'Light falls by this fraction across the image'),
    'camera_blur_px': (0.9, 'Lens blur, Gaussian sigma in pixels'),
    'camera_image_noise': (2.0, 'Sensor noise, 8-bit digital numbers'),
    'camera_seed': (0, 'Seed of the sensor noise'),
}


def sim_camera_config(params: dict) -> CameraConfig:
    """The synthetic camera of the hardware-in-the-loop world from the
    ``SIM_CAMERA_PARAMETERS`` values ``params`` (camera_sim_node's parameters)."""
    return CameraConfig(rate_hz=float(params['camera_rate_hz']),
                        latency_s=float(params['camera_latency_s']),
                        brightness=float(params['camera_brightness']),
                        gradient=float(params['camera_gradient']),
                        blur_sigma_px=float(params['camera_blur_px']),
                        noise_std=float(params['camera_image_noise']),
                        seed=int(params['camera_seed']))


def camera_homography(cfg: CameraConfig) -> np.ndarray:
    """The synthetic camera's arena -> pixel homography (3x3)."""
    s = (cfg.height / 2.0) / cfg.view_half_m
    L = cfg.view_half_m
    cu, cv = cfg.width / 2.0, cfg.height / 2.0
    a = math.radians(cfg.rotation_deg)
    ca, sa = math.cos(a), math.sin(a)
    arena = np.array([[-L, L], [L, L], [L, -L], [-L, -L]], dtype=np.float32)
    pix = []
    for x, y in arena:
        shrink = 1.0 - cfg.tilt * (y / L + 1.0) / 2.0   # the far (top) edge appears smaller
        u, v = x * s * shrink, -y * s * (1.0 - cfg.tilt / 2.0)
        pix.append([cu + ca * u - sa * v, cv + sa * u + ca * v])
    return cv2.getPerspectiveTransform(arena, np.array(pix, dtype=np.float32)).astype(float)


def lens_matrix(cfg: CameraConfig) -> np.ndarray:
    """The synthetic lens's camera matrix (3x3): ``focal_px``, centred on the image."""
    return np.array([[cfg.focal_px, 0.0, cfg.width / 2.0],
                     [0.0, cfg.focal_px, cfg.height / 2.0], [0.0, 0.0, 1.0]])


def camera_lens(cfg: CameraConfig) -> Lens | None:
    """The synthetic camera's lens: radial distortion ``k1``, ``k2`` about the image
    centre with focal length ``focal_px``; None without distortion."""
    if cfg.k1 == 0.0 and cfg.k2 == 0.0:
        return None
    return Lens(lens_matrix(cfg), cfg.k1, cfg.k2)


def distortion_maps(cfg: CameraConfig) -> tuple[np.ndarray, np.ndarray] | None:
    """cv2.remap maps that distort an ideal (pinhole) image by the lens: for every pixel
    of the distorted image, where it lies in the ideal one. None without distortion."""
    lens = camera_lens(cfg)
    if lens is None:
        return None
    v, u = np.mgrid[0:cfg.height, 0:cfg.width].astype(float)
    ideal = lens.undistort(np.stack([u, v], axis=-1)).astype(np.float32)
    return ideal[..., 0], ideal[..., 1]


def circle_polygon(H: np.ndarray, x: float, y: float, r: float, n: int = 64) -> np.ndarray:
    """A circle of the arena as an image polygon, fixed point with 4 fractional bits."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    pts = apply_homography(H, np.column_stack([x + r * np.cos(t), y + r * np.sin(t)]))
    return np.round(pts * 16.0).astype(np.int32)


def _bgr(rgb: Sequence[int]) -> tuple[int, int, int]:
    return int(rgb[2]), int(rgb[1]), int(rgb[0])


class CameraRenderer:
    """Draws the arena from above; see the module docstring."""

    def __init__(self, cfg: CameraConfig = CameraConfig(),
                 markers: ArenaMarkers | None = None,
                 geometry: CoverGeometry | None = None, arena_half_m: float = 1.0) -> None:
        self.cfg = cfg
        self.geometry = geometry or CoverGeometry()
        markers = markers or ArenaMarkers()
        self.H = camera_homography(cfg)
        self.rng = np.random.default_rng(cfg.seed)
        self.background = self._background(markers, arena_half_m)
        self.gain = self._gain_field()
        self.maps = distortion_maps(cfg)

    # -- static parts -------------------------------------------------------------------
    def _background(self, markers: ArenaMarkers, half: float) -> np.ndarray:
        cfg = self.cfg
        h, w = cfg.height, cfg.width
        coarse = self.rng.normal(0.0, 1.0, (h // 16 + 2, w // 16 + 2)).astype(np.float32)
        blotches = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
        grain = self.rng.normal(0.0, 0.5, (h, w)).astype(np.float32)
        pattern = 1.0 + cfg.texture * (0.7 * blotches + 0.3 * grain)
        floor = np.array(_bgr(FLOOR_RGB), dtype=np.float32)
        img = np.clip(pattern[..., None] * floor, 0, 255).astype(np.uint8)
        border = apply_homography(self.H, np.array([[-half, -half], [half, -half],
                                                    [half, half], [-half, half]]))
        cv2.polylines(img, [np.round(border * 16).astype(np.int32)], True,
                      _bgr(BORDER_RGB), 2, cv2.LINE_AA, 4)
        dictionary = cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARY)
        for marker_id in markers.ids:
            corners = markers.corners(marker_id)
            cx, cy = np.mean(corners, axis=0)
            q = 0.75 * markers.side            # a white quiet zone around the tag
            quiet = np.array([[cx - q, cy + q], [cx + q, cy + q], [cx + q, cy - q],
                              [cx - q, cy - q]])
            cv2.fillPoly(img, [np.round(apply_homography(self.H, quiet) * 16).astype(np.int32)],
                         (250, 250, 250), cv2.LINE_AA, 4)
            side_px = 120
            tag = cv2.aruco.generateImageMarker(dictionary, marker_id, side_px)
            src = np.array([[0, 0], [side_px, 0], [side_px, side_px], [0, side_px]],
                           dtype=np.float32)
            dst = apply_homography(self.H, corners).astype(np.float32)
            warp = cv2.getPerspectiveTransform(src, dst)
            warped = cv2.warpPerspective(cv2.cvtColor(tag, cv2.COLOR_GRAY2BGR), warp, (w, h),
                                         flags=cv2.INTER_AREA)
            mask = cv2.warpPerspective(np.full((side_px, side_px), 255, np.uint8), warp, (w, h),
                                       flags=cv2.INTER_LINEAR)
            alpha = (mask.astype(np.float32) / 255.0)[..., None]
            img = (alpha * warped + (1.0 - alpha) * img).astype(np.uint8)
        return img

    def _gain_field(self) -> np.ndarray:
        cfg = self.cfg
        v, u = np.mgrid[0:cfg.height, 0:cfg.width].astype(np.float32)
        diagonal = (u / cfg.width + v / cfg.height) / 2.0          # 0 .. 1 corner to corner
        r2 = ((u - cfg.width / 2) ** 2 + (v - cfg.height / 2) ** 2) / (cfg.width / 2) ** 2
        vignette = 1.0 - 0.08 * r2
        return (cfg.brightness * (1.0 - cfg.gradient * diagonal) * vignette).astype(np.float32)

    # -- frames -------------------------------------------------------------------------
    def draw_covers(self, covers: Sequence[Cover]) -> np.ndarray:
        """The noiseless, evenly lit scene (BGR uint8): background plus covers."""
        img = self.background.copy()
        g = self.geometry
        for c in sorted(covers, key=lambda c: c.radius):
            H = self.H
            cv2.fillPoly(img, [circle_polygon(H, c.x, c.y, c.radius)], _bgr(PLATE_RGB),
                         cv2.LINE_AA, 4)
            cv2.polylines(img, [circle_polygon(H, c.x, c.y, c.radius)], True, _bgr(RIM_RGB),
                          1, cv2.LINE_AA, 4)
            colour = _bgr(c.rgb)
            cv2.fillPoly(img, [circle_polygon(H, c.x, c.y, g.large_radius * c.radius)], colour,
                         cv2.LINE_AA, 4)
            sx = c.x + g.small_offset * c.radius * math.cos(c.yaw)
            sy = c.y + g.small_offset * c.radius * math.sin(c.yaw)
            cv2.fillPoly(img, [circle_polygon(H, sx, sy, g.small_radius * c.radius, 48)], colour,
                         cv2.LINE_AA, 4)
        return img

    def render(self, covers: Sequence[Cover], rng: np.random.Generator | None = None
               ) -> np.ndarray:
        """One camera frame (BGR uint8) of ``covers``: light, blur and noise applied."""
        return self.expose(self.draw_covers(covers), rng)

    def expose(self, scene: np.ndarray, rng: np.random.Generator | None = None
               ) -> np.ndarray:
        """An ideal scene (BGR uint8) as the camera delivers it: lens distortion, light,
        white balance, blur and noise."""
        cfg = self.cfg
        rng = rng if rng is not None else self.rng
        if self.maps is not None:
            scene = cv2.remap(scene, *self.maps, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REPLICATE)
        gain = self.gain[..., None] * np.array(cfg.white_balance[::-1], dtype=np.float32)
        img = scene.astype(np.float32) * gain
        if cfg.blur_sigma_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma_px)
        if cfg.noise_std > 0:
            img += rng.standard_normal(img.shape, dtype=np.float32) * cfg.noise_std
        return np.clip(img, 0, 255).astype(np.uint8)

    def checkerboard(self, rvec: Sequence[float], tvec: Sequence[float],
                     pattern: tuple[int, int] = (9, 6), square: float = 0.03) -> np.ndarray:
        """A printed checkerboard of ``pattern`` inner corners and ``square`` m squares
        (a white margin of one square) at pose ``rvec``, ``tvec`` (OpenCV: board ->
        camera, m; its origin the first inner corner) before a grey wall, seen through
        the lens: the pinhole image of ``lens_matrix``, then :meth:`expose`."""
        cfg = self.cfg
        cols, rows = pattern[0] + 1, pattern[1] + 1          # squares
        px = 40                                              # texture pixels per square
        tex = np.full(((rows + 2) * px, (cols + 2) * px), 245, np.uint8)
        for r in range(rows):
            for c in range(cols):
                if (r + c) % 2 == 0:
                    tex[(r + 1) * px:(r + 2) * px, (c + 1) * px:(c + 2) * px] = 20
        R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=float))
        board_to_ideal = lens_matrix(cfg) @ np.column_stack(
            [R[:, 0], R[:, 1], np.asarray(tvec, dtype=float)])
        tex_to_board = np.array([[square / px, 0.0, -2.0 * square],
                                 [0.0, square / px, -2.0 * square], [0.0, 0.0, 1.0]])
        scene = np.full((cfg.height, cfg.width, 3), 120, np.uint8)
        cv2.warpPerspective(cv2.cvtColor(tex, cv2.COLOR_GRAY2BGR),
                            board_to_ideal @ tex_to_board, (cfg.width, cfg.height),
                            dst=scene, flags=cv2.INTER_AREA,
                            borderMode=cv2.BORDER_TRANSPARENT)
        return self.expose(scene)


class SimCamera:
    """Frame timing of the synthetic camera: a frame every 1/rate_hz s, delivered
    ``latency_s`` after its capture and stamped with the capture time."""

    def __init__(self, renderer: CameraRenderer) -> None:
        self.renderer = renderer
        self.period = 1.0 / renderer.cfg.rate_hz
        self.latency = renderer.cfg.latency_s
        self._next = None
        self._pending: deque[tuple[float, np.ndarray]] = deque()

    def capture(self, t: float, covers: Sequence[Cover]) -> bool:
        """Capture a frame at time ``t`` if one is due; return whether it did."""
        if self._next is not None and t < self._next:
            return False
        self._next = (t if self._next is None else self._next) + self.period
        if self._next <= t:                 # called late: keep the rate, skip the backlog
            self._next = t + self.period
        self._pending.append((t, self.renderer.render(covers)))
        return True

    def ready(self, t: float) -> list[tuple[float, np.ndarray]]:
        """Frames whose latency has passed by time ``t``: (capture time, image), oldest first."""
        out = []
        while self._pending and self._pending[0][0] + self.latency <= t:
            out.append(self._pending.popleft())
        return out
