"""The overhead camera tracker of thesis 5.1 (Figs. 5.2-5.4): robots' poses from an image.

Every robot carries a cover with two circles of its colour (Fig. 5.2): a large one at
its centre and a small one toward its heading. Per frame (:meth:`CameraTracker.update`):

1. Colour classification in HSV, after the calibration's white balance (channel gains
   measured on the white cover plates by ``camera_calibrate --colors``). A pixel is
   coloured when its saturation is above ``saturation_min`` and its value above
   ``value_fraction`` of the image's reference brightness (the ``reference_percentile``
   of V: the white covers), so the thresholds follow the light from dim to bright; hue
   is unchanged by the light's gain. Its hue picks the cover colour it is nearest to
   (the calibration's measured ``cover_colors``, else the fleet file's), within
   ``hue_tolerance`` (at most 45 % of the gap to the next colour); a coloured pixel far
   from every cover colour is of an unknown colour.
2. Circles: connected regions per colour; each region's centre is its
   saturation-weighted centroid (sub-pixel), mapped to the arena by the calibration's
   homography, after the lens's undistortion when the calibration knows the lens
   (:mod:`swarm_bridge.arena_calibration`; only the few centres are undistorted, not
   the image); its area in the arena tells a large circle from a small one (the
   colour's robots have one type, hence one radius).
3. Covers: each large circle is paired with a small one at the cover's circle offset
   (Hungarian on the offset error). Position = the large circle's centre; heading =
   the bearing from the large to the small circle (Fig. 5.3). The thesis states that
   bearing clockwise in the image; in the map frame (REP 103, y up) it is the yaw
   ``atan2(dy, dx)``, counter-clockwise from +x, as every pose of this project.
4. Identity: per colour, the covers are matched to the robots of that colour by the
   Hungarian method (scipy ``linear_sum_assignment``) on the distance to each robot's
   predicted position (last position plus last velocity times the elapsed time), gated
   by how far a robot can have moved; so two robots of one colour keep their ids.

Bad or odd input, never guessed: a robot not matched for ``missing_timeout_s`` is
reported missing (and no pose is given for it until it is matched again); covers of an
unknown colour are ignored and counted; two covers of one colour closer than one robot
diameter are reported ambiguous (counted and drawn, neither used), never merged; a large
circle without its small one (heading unknown) is counted as incomplete.

Pure module (numpy, scipy, OpenCV; no rclpy).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import math

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from swarm_bridge.arena_calibration import Calibration
from swarm_bridge.camera_render import CoverGeometry
from swarm_common.fleet import RobotSpec

UNKNOWN = 254      # label of coloured pixels of no fleet colour
NONE = 255         # label of uncoloured pixels
FAR = 1e6          # cost of a forbidden pairing


class TrackerError(ValueError):
    """A fleet the tracker cannot tell apart; the message names the entry and the fix."""


@dataclass(frozen=True)
class TrackerConfig:
    """Thresholds and timing of :class:`CameraTracker` (defaults: config/camera.yaml)."""

    saturation_min: int = 100           # 0-255: half the covers' colours' saturation
    value_fraction: float = 0.2         # V threshold as a fraction of the reference V
    reference_percentile: float = 99.0  # the image's reference brightness (white covers)
    hue_tolerance: float = 12.0         # OpenCV hue units (2 deg each)
    min_area_fraction: float = 0.35     # of the smallest circle's area: smaller is noise
    pairing_tolerance: float = 0.25     # small circle offset error allowed, x cover radius
    gate_m: float = 0.08                # a robot moves at most this plus max_speed * dt
    max_speed: float = 0.3              # m/s
    missing_timeout_s: float = 1.0      # unmatched this long: missing
    arena_half_m: float = 1.0           # the arena: |x|, |y| <= this (plus roi_margin_m)
    roi_margin_m: float = 0.1


@dataclass
class Detection:
    """A cover found in one frame: colour, pose (m, rad CCW), pixel centres, flags."""

    color: str
    x: float
    y: float
    yaw: float
    large_px: tuple[float, float]
    small_px: tuple[float, float] | None
    ambiguous: bool = False
    agent_id: int | None = None


@dataclass
class FrameResult:
    """One frame: poses of the robots matched now, and what was counted."""

    stamp: float
    poses: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    detections: list[Detection] = field(default_factory=list)
    missing: list[int] = field(default_factory=list)
    unknown_covers: int = 0
    ambiguous: int = 0
    incomplete: int = 0
    unassigned: int = 0
    reference_value: float = 0.0


@dataclass
class _Track:
    robot: RobotSpec
    x: float = math.nan
    y: float = math.nan
    vx: float = 0.0
    vy: float = 0.0
    t: float = -math.inf
    seen: bool = False


def hue_of(rgb: Sequence[int]) -> float:
    """OpenCV hue (0-180) of an RGB colour."""
    pixel = np.array([[[rgb[2], rgb[1], rgb[0]]]], dtype=np.float32) / 255.0
    return float(cv2.cvtColor(pixel, cv2.COLOR_BGR2HSV)[0, 0, 0]) / 2.0


def hue_lut(hues: Sequence[float], tolerance: float) -> np.ndarray:
    """Lookup table OpenCV hue (0-179) -> index of the nearest colour, UNKNOWN if none is
    within ``tolerance`` (capped at 45 % of the gap to that colour's nearest neighbour)."""
    hues = np.asarray(hues, dtype=float)
    h = np.arange(256, dtype=float)
    lut = np.full(256, UNKNOWN, dtype=np.uint8)
    if len(hues) == 0:
        return lut
    d = np.abs((h[:, None] - hues[None, :] + 90.0) % 180.0 - 90.0)
    tol = np.full(len(hues), tolerance)
    for i in range(len(hues)):
        others = np.delete(hues, i)
        if len(others):
            gap = np.min(np.abs((others - hues[i] + 90.0) % 180.0 - 90.0))
            tol[i] = min(tolerance, 0.45 * gap)
    best = np.argmin(d, axis=1)
    ok = d[np.arange(256), best] <= tol[best]
    lut[ok] = best[ok]
    lut[180:] = UNKNOWN
    return lut


class CameraTracker:
    """Robots' poses from overhead images; see the module docstring."""

    def __init__(self, robots: Sequence[RobotSpec], colors: dict[str, tuple[int, int, int]],
                 calibration: Calibration, config: TrackerConfig = TrackerConfig(),
                 geometry: CoverGeometry | None = None,
                 initial_poses: dict[int, tuple[float, float]] | None = None) -> None:
        self.cfg = config
        self.geometry = geometry or CoverGeometry()
        self.calibration = calibration
        self.names = sorted({r.color for r in robots})
        if calibration.cover_colors is not None:       # measured under the arena's light
            colors = calibration.cover_colors
            where = ("the calibration file's cover_colors; run camera_calibrate --colors "
                     'with every robot at its start pose')
        else:
            where = 'cover_colors; add them to the fleet file'
        missing = [n for n in self.names if n not in colors]
        if missing:
            raise TrackerError(f'robot colours {missing} have no RGB in {where}')
        self.colors = {n: tuple(colors[n]) for n in self.names}
        balance = calibration.white_balance
        self._balance = None if balance is None or np.allclose(balance, 1.0) else np.diag(
            [balance[2], balance[1], balance[0]]).astype(np.float32)   # BGR
        self.radius: dict[str, float] = {}
        for name in self.names:
            group = [r for r in robots if r.color == name]
            if len({(r.type, r.radius) for r in group}) > 1:
                raise TrackerError(
                    f'robots {[r.id for r in group]} share the colour {name} but not '
                    'their type and radius; give each type its own cover colour')
            self.radius[name] = group[0].radius
        self.lut = hue_lut([hue_of(colors[n]) for n in self.names], config.hue_tolerance)
        self.tracks = {r.id: _Track(r) for r in robots}
        for k, (x, y) in (initial_poses or {}).items():
            if k in self.tracks:
                self.tracks[k].x, self.tracks[k].y = float(x), float(y)
        self._roi = None
        self._roi_size = None
        self._t0: float | None = None

    # -- 1. colours ---------------------------------------------------------------------
    def _roi_mask(self, shape: tuple[int, int]) -> np.ndarray:
        if self._roi is None or self._roi_size != shape:
            h = self.cfg.arena_half_m + self.cfg.roi_margin_m
            corners = self.calibration.to_pixels(np.array([[-h, -h], [h, -h], [h, h],
                                                           [-h, h]]))
            self._roi = np.zeros(shape, np.uint8)
            cv2.fillPoly(self._roi, [np.round(corners).astype(np.int32)], 255)
            self._roi_size = shape
        return self._roi

    def classify(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Per-pixel labels (colour index, UNKNOWN or NONE), saturation, reference V."""
        if self._balance is not None:
            image = cv2.transform(image, self._balance)
        hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
        hue, sat, val = cv2.split(hsv)
        v_ref = float(np.percentile(val[::4, ::4], self.cfg.reference_percentile))
        v_min = max(8.0, self.cfg.value_fraction * v_ref)
        coloured = cv2.inRange(hsv, (0, self.cfg.saturation_min, int(v_min)), (255, 255, 255))
        coloured = cv2.bitwise_and(coloured, self._roi_mask(coloured.shape))
        labels = cv2.LUT(hue, self.lut)
        labels[coloured == 0] = NONE
        return labels, sat, v_ref

    # -- 2. circles ---------------------------------------------------------------------
    def _coloured_regions(self, labels: np.ndarray, sat: np.ndarray) -> dict[int, list]:
        """Regions of coloured pixels grouped by the label most of their pixels carry
        (a few pixels of a neighbouring hue inside a circle do not split it)."""
        groups: dict[int, list] = {}
        for region in self._regions(cv2.compare(labels, NONE, cv2.CMP_NE), sat, (0, 0),
                                    labels, self._min_pixels(labels.shape)):
            groups.setdefault(region[5], []).append(region[:5])
        return groups

    def _regions(self, binary: np.ndarray, sat: np.ndarray, origin: tuple[int, int],
                 labels: np.ndarray | None = None, min_pixels: int = 4) -> list[tuple]:
        """Connected regions of ``binary`` (a window of ``sat`` at ``origin``): (pixel
        centre, arena centre, arena area m^2, median saturation, bounding box x0, y0, x1,
        y1, majority label or -1). The centre is the saturation-weighted centroid over the
        region and a one-pixel ring (the blurred edge: sub-pixel centres)."""
        n, lab, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=4)
        out = []
        s0 = self.cfg.saturation_min / 2.0
        rows, cols = binary.shape
        for i in range(1, n):
            x, y, w, h, area = stats[i]
            if area < min_pixels:
                continue
            x0, y0 = max(x - 2, 0), max(y - 2, 0)
            x1, y1 = min(x + w + 2, cols), min(y + h + 2, rows)
            core = (lab[y0:y1, x0:x1] == i).astype(np.uint8)
            ring = cv2.dilate(core, np.ones((3, 3), np.uint8))
            s = sat[y0:y1, x0:x1].astype(np.float32)
            s1 = float(np.median(s[core > 0]))
            weight = np.clip((s - s0) / max(s1 - s0, 1.0), 0.0, 1.0) * ring
            total = float(weight.sum())
            if total <= 0:
                continue
            vv, uu = np.mgrid[y0:y1, x0:x1]
            centre = np.array([float((weight * uu).sum()) / total + origin[0],
                               float((weight * vv).sum()) / total + origin[1]])
            arena = self.calibration.to_arena(centre)
            label = -1 if labels is None else int(np.bincount(
                labels[y0:y1, x0:x1][core > 0], minlength=256).argmax())
            out.append((centre, arena, total * self.calibration.area_per_pixel(centre), s1,
                        (x0 + origin[0], y0 + origin[1], x1 + origin[0], y1 + origin[1]),
                        label))
        return out

    def _min_pixels(self, shape: tuple[int, int]) -> int:
        """Half the pixels of the smallest circle kept (``min_area_fraction`` of the
        smallest small circle) where pixels are largest: smaller regions are noise."""
        if getattr(self, '_min_px_shape', None) != shape:
            h, w = shape
            smallest = min(math.pi * (self.geometry.small_radius * r) ** 2
                           for r in self.radius.values()) * self.cfg.min_area_fraction
            largest = max(self.calibration.area_per_pixel(np.array(c, dtype=float))
                          for c in ((0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)))
            self._min_px = max(4, int(0.5 * smallest / largest))
            self._min_px_shape = shape
        return self._min_px

    def _size(self, region: tuple) -> float:
        """A region's radius in the arena (m), less half a pixel of blurred edge."""
        centre, _, area = region[0], region[1], region[2]
        half_pixel = 0.5 * math.sqrt(self.calibration.area_per_pixel(centre))
        return math.sqrt(area / math.pi) - half_pixel

    def _split(self, labels: np.ndarray, sat: np.ndarray, index: int, region: tuple
               ) -> list[tuple]:
        """A region too large for one circle, thresholded again at 80 % of its median
        saturation: a large and a small circle joined by their blurred, noisy gap part."""
        _, _, _, s1, (x0, y0, x1, y1) = region
        window = labels[y0:y1, x0:x1] == index
        binary = (window & (sat[y0:y1, x0:x1] >= 0.8 * s1)).astype(np.uint8) * 255
        return self._regions(binary, sat[y0:y1, x0:x1], (x0, y0))

    # -- 3. covers ----------------------------------------------------------------------
    def detect(self, image: np.ndarray) -> FrameResult:
        """Covers in one image (no identities): detections and counts."""
        labels, sat, v_ref = self.classify(image)
        g = self.geometry
        result = FrameResult(stamp=math.nan, reference_value=v_ref)
        smallest = min(math.pi * (g.small_radius * r) ** 2 for r in self.radius.values())
        groups = self._coloured_regions(labels, sat)
        for index, name in enumerate(self.names):
            R = self.radius[name]
            r_large, r_small = g.large_radius * R, g.small_radius * R
            larges, smalls = [], []
            joined = (r_large + math.hypot(r_large, r_small)) / 2.0
            regions = []
            for region in groups.get(index, []):
                parts = []
                if self._size(region) > joined:       # the two circles run together: split
                    parts = self._split(labels, sat, index, region)
                regions.extend(parts if len(parts) > 1 else [region])
            for region in regions:
                px, xy, r = region[0], region[1], self._size(region)
                if r < self.cfg.min_area_fraction ** 0.5 * r_small:
                    continue
                if r < (r_large + r_small) / 2.0:
                    smalls.append((px, xy))
                elif r <= 1.3 * r_large:
                    larges.append((px, xy, False))
                else:   # two large circles run together: covers overlapping
                    larges.append((px, xy, True))
            result.detections.extend(self._pair(name, R, larges, smalls, result))
        # printed colours are saturated through and through; noise in the dark is not
        unknown = [region[1] for region in groups.get(UNKNOWN, [])
                   if math.pi * self._size(region) ** 2 >= self.cfg.min_area_fraction * smallest
                   and region[3] >= 1.3 * self.cfg.saturation_min]
        result.unknown_covers = _clusters(unknown, 2.0 * max(self.radius.values()))
        return result

    def _pair(self, name: str, R: float, larges: list, smalls: list,
              result: FrameResult) -> list[Detection]:
        g = self.geometry
        offset, tol = g.small_offset * R, self.cfg.pairing_tolerance * R
        ambiguous = [merged for _, _, merged in larges]
        for i in range(len(larges)):
            for j in range(i + 1, len(larges)):
                if np.hypot(*(larges[i][1] - larges[j][1])) < 2.0 * R:
                    ambiguous[i] = ambiguous[j] = True
        cost = np.full((len(larges), len(smalls)), FAR)
        for i, (_, lxy, _) in enumerate(larges):
            for j, (_, sxy) in enumerate(smalls):
                err = abs(float(np.hypot(*(sxy - lxy))) - offset)
                if err <= tol:
                    cost[i, j] = err
        partner: dict[int, int] = {}
        if cost.size:
            rows, cols = linear_sum_assignment(cost)
            partner = {int(i): int(j) for i, j in zip(rows, cols) if cost[i, j] < FAR}
        out = []
        for i, (lpx, lxy, _) in enumerate(larges):
            j = partner.get(i)
            if j is None:
                yaw, spx = math.nan, None
            else:
                spx, sxy = smalls[j]
                yaw = math.atan2(sxy[1] - lxy[1], sxy[0] - lxy[0])
            det = Detection(name, float(lxy[0]), float(lxy[1]), yaw,
                            (float(lpx[0]), float(lpx[1])),
                            None if spx is None else (float(spx[0]), float(spx[1])),
                            ambiguous[i])
            if det.ambiguous:
                result.ambiguous += 1
            elif j is None:
                result.incomplete += 1
            out.append(det)
        return out

    # -- 4. identities ------------------------------------------------------------------
    def update(self, image: np.ndarray, stamp: float) -> FrameResult:
        """Detect the covers in ``image`` (captured at ``stamp`` s) and match them to the
        robots; return the poses of the robots matched in this frame."""
        if self._t0 is None:
            self._t0 = stamp
        result = self.detect(image)
        result.stamp = stamp
        usable = [d for d in result.detections if not d.ambiguous and not math.isnan(d.yaw)]
        for name in self.names:
            dets = [d for d in usable if d.color == name]
            tracks = [t for t in self.tracks.values() if t.robot.color == name]
            result.unassigned += self._assign(tracks, dets, stamp, result)
        for k, track in self.tracks.items():
            last = track.t if track.seen else self._t0
            if stamp - last > self.cfg.missing_timeout_s:
                result.missing.append(k)
        return result

    def _assign(self, tracks: list[_Track], dets: list[Detection], stamp: float,
                result: FrameResult) -> int:
        if not dets:
            return 0
        cost = np.full((len(tracks), len(dets)), FAR)
        for i, tr in enumerate(tracks):
            if math.isnan(tr.x):            # never seen, no initial pose: anywhere
                cost[i] = [1.0 for _ in dets]
                continue
            dt = min(max(stamp - tr.t, 0.0), 1e3) if tr.seen else 0.0
            px, py = tr.x + tr.vx * dt, tr.y + tr.vy * dt
            gate = self.cfg.gate_m + self.cfg.max_speed * (dt if tr.seen else 1e3)
            for j, d in enumerate(dets):
                dist = math.hypot(d.x - px, d.y - py)
                if dist <= gate:
                    cost[i, j] = dist
        rows, cols = linear_sum_assignment(cost)
        used = 0
        for i, j in zip(rows, cols):
            if cost[i, j] >= FAR:
                continue
            tr, d = tracks[i], dets[j]
            if tr.seen and stamp > tr.t:
                dt = stamp - tr.t
                a = min(1.0, dt / 0.5)                  # velocity over about half a second
                tr.vx += a * ((d.x - tr.x) / dt - tr.vx)
                tr.vy += a * ((d.y - tr.y) / dt - tr.vy)
            tr.x, tr.y, tr.t, tr.seen = d.x, d.y, stamp, True
            d.agent_id = tr.robot.id
            result.poses[tr.robot.id] = (d.x, d.y, d.yaw)
            used += 1
        return len(dets) - used


def _clusters(points: list[np.ndarray], distance: float) -> int:
    """Number of groups of points chained closer than ``distance`` (covers of 2 circles)."""
    group = list(range(len(points)))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i
    for i in range(len(points)):
        for j in range(i):
            if np.hypot(*(points[i] - points[j])) < distance:
                group[root(i)] = root(j)
    return len({root(i) for i in range(len(points))})


def annotate(image: np.ndarray, result: FrameResult, calibration: Calibration,
             radius: dict[int, float]) -> np.ndarray:
    """A copy of ``image`` with every detection drawn (thesis Fig. 5.4): id and heading
    for matched covers, 'ambiguous' or '?' for the rest."""
    out = image.copy()
    for d in result.detections:
        u, v = (int(round(c)) for c in d.large_px)
        if d.agent_id is not None:
            colour, text = (0, 255, 0), f'{d.agent_id}'
        elif d.ambiguous:
            colour, text = (0, 0, 255), 'ambiguous'
        else:
            colour, text = (0, 200, 255), '?'
        r_m = radius.get(d.agent_id, 0.1) if d.agent_id is not None else 0.1
        edge = calibration.to_pixels(np.array([d.x + r_m, d.y]))
        r_px = max(4, int(round(float(np.hypot(*(edge - np.array(d.large_px)))))))
        cv2.circle(out, (u, v), r_px, colour, 1, cv2.LINE_AA)
        if d.small_px is not None:
            cv2.line(out, (u, v), tuple(int(round(c)) for c in d.small_px), colour, 1,
                     cv2.LINE_AA)
        cv2.putText(out, text, (u + r_px, v - r_px), cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour,
                    1, cv2.LINE_AA)
    status = (f'missing {result.missing}  ambiguous {result.ambiguous}  '
              f'unknown {result.unknown_covers}')
    cv2.putText(out, status, (8, out.shape[0] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (255, 255, 255), 1, cv2.LINE_AA)
    return out
