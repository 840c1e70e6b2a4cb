"""camera_calibrate: write the overhead camera's pixel -> arena homography (thesis 5.1).

  camera_calibrate --source /dev/video0 --out camera_calibration.yaml
  camera_calibrate --source arena.png --out camera_calibration.yaml
  camera_calibrate --sim --out camera_calibration.yaml     # the synthetic camera

Place ArUco markers 0-3 (dictionary 4x4_50, printed ``--marker-side`` metres wide) at
the arena corners ``--corners`` (default: (-1.08, -1.08), (1.08, -1.08), (1.08, 1.08),
(-1.08, 1.08), the 2 x 2 m arena of thesis 5.2 plus a margin), upright (top edge toward
+y), at the height of the robots' covers. The command grabs a frame (a device or video
is read until the markers are found, for up to ``--tries`` frames), fits the homography
to the 16 marker corners and writes it with its residual. Bad input gives one line and
exit status 2.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import cv2
import numpy as np

from swarm_bridge.arena_calibration import ArenaMarkers, calibrate, CalibrationError


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--source', help='V4L2 device (/dev/videoN or N), image or video file')
    src.add_argument('--sim', action='store_true', help='the synthetic camera (camera_render)')
    p.add_argument('--out', required=True, help='calibration YAML to write')
    p.add_argument('--marker-side', type=float, default=ArenaMarkers().side,
                   help='printed marker side, m')
    p.add_argument('--corners', type=float, nargs=8, default=None,
                   metavar=('X0', 'Y0', 'X1', 'Y1', 'X2', 'Y2', 'X3', 'Y3'),
                   help='centres of markers 0-3 in the arena, m')
    p.add_argument('--tries', type=int, default=30, help='frames to read from a device/video')
    p.add_argument('--save-image', default=None, help='also write the frame used (PNG)')
    return p.parse_args(argv)


def grab(source: str, markers: ArenaMarkers, tries: int) -> np.ndarray:
    """A frame of ``source`` showing the markers (an image file, or the first of ``tries``
    device/video frames in which all four are found)."""
    path = pathlib.Path(source)
    if path.suffix.lower() in ('.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff'):
        image = cv2.imread(str(path))
        if image is None:
            raise CalibrationError(f'cannot read image {source}: check the path and format')
        return image
    capture = cv2.VideoCapture(int(source) if source.isdigit() else source)
    if not capture.isOpened():
        raise CalibrationError(f'cannot open camera {source}: check the device or file path')
    last = None
    try:
        for _ in range(max(1, tries)):
            ok, frame = capture.read()
            if not ok or frame is None:
                break
            last = frame
            try:
                calibrate(frame, markers)
                return frame
            except CalibrationError:
                continue
    finally:
        capture.release()
    if last is None:
        raise CalibrationError(f'camera {source} gave no frame: is it in use or empty?')
    return last


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    markers = ArenaMarkers(side=args.marker_side) if args.corners is None else ArenaMarkers(
        centres=tuple(zip(args.corners[0::2], args.corners[1::2])), side=args.marker_side)
    try:
        if args.sim:
            from swarm_bridge.camera_render import CameraRenderer
            image = CameraRenderer(markers=markers).render([])
        else:
            image = grab(args.source, markers, args.tries)
        if args.save_image:
            cv2.imwrite(args.save_image, image)
        cal = calibrate(image, markers)
        cal.save(args.out)
    except (CalibrationError, OSError) as exc:
        print(f'camera_calibrate: {exc}', file=sys.stderr)
        return 2
    print(f'camera_calibrate: {args.out} written ({cal.size[0]}x{cal.size[1]} image, corner '
          f'residual {cal.rms_m * 1000:.1f} mm RMS)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
