"""camera_calibrate: calibrate the overhead camera (thesis 5.1): lens, arena, colours.

Three steps, in this order, each updating one calibration YAML (``--out``), the
``calibration_file`` of camera_tracker_node:

  camera_calibrate --lens --source /dev/video0 --out camera_calibration.yaml
  camera_calibrate --source /dev/video0 --out camera_calibration.yaml
  camera_calibrate --colors --source /dev/video0 --out camera_calibration.yaml

1. ``--lens`` (a wide-angle lens; skip it for a lens without visible distortion): hold a
   printed checkerboard (``--board`` inner corners, ``--square`` m squares, flat on card)
   before the camera, tilted by 20-40 degrees, at ten or more places that together cover
   the whole image, corners included. From a device or video a view is kept every
   ``--every`` frames in which the whole board is found; image files are taken as views.
   Zhang's method (cv2.calibrateCamera) gives the camera matrix and the radial
   distortion k1, k2. This starts a new file: the arena and colours follow.
2. Arena: ArUco markers 0-3 (dictionary 4x4_50, printed ``--marker-side`` metres wide) at
   the arena corners ``--corners`` (default: (-1.08, -1.08), (1.08, -1.08), (1.08, 1.08),
   (-1.08, 1.08), the 2 x 2 m arena of thesis 5.2 plus a margin), upright (top edge toward
   +y), at the height of the robots' covers. The homography is fitted to the 16 marker
   corners, undistorted first by the file's lens; the file's lens and colours are kept.
3. ``--colors``: every robot at its start pose (``--poses``; by default those of
   scripts/hil_demo.py, config/hil.yaml's ``initial_poses``, else the fleet file's x, y,
   yaw), the arena lit as for the runs. Measures the white balance on the white
   cover plates and each cover colour (swarm_bridge.camera_colors).

``--sim`` uses the synthetic camera (camera_render) instead of ``--source``, with
``--k1``/``--k2``/``--white-balance`` to try a distorting lens or a camera balanced for
another light. Bad input gives one line and exit status 2.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import cv2
import numpy as np
import yaml

from swarm_bridge.arena_calibration import (
    ArenaMarkers,
    calibrate,
    calibrate_lens,
    Calibration,
    CalibrationError,
    find_checkerboard,
    Lens,
)

IMAGE_SUFFIXES = ('.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff')


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument('--source', nargs='+',
                     help='V4L2 device (/dev/videoN or N), video file or image file(s)')
    src.add_argument('--sim', action='store_true', help='the synthetic camera (camera_render)')
    step = p.add_mutually_exclusive_group()
    step.add_argument('--lens', action='store_true',
                      help='step 1: lens distortion from checkerboard views')
    step.add_argument('--colors', action='store_true',
                      help='step 3: white balance and cover colours, robots at start poses')
    p.add_argument('--out', required=True, help='calibration YAML to write or update')
    p.add_argument('--marker-side', type=float, default=ArenaMarkers().side,
                   help='printed marker side, m')
    p.add_argument('--corners', type=float, nargs=8, default=None,
                   metavar=('X0', 'Y0', 'X1', 'Y1', 'X2', 'Y2', 'X3', 'Y3'),
                   help='centres of markers 0-3 in the arena, m')
    p.add_argument('--board', default='9x6', help='checkerboard inner corners, COLSxROWS')
    p.add_argument('--square', type=float, default=0.03, help='checkerboard square, m')
    p.add_argument('--views', type=int, default=15, help='checkerboard views to collect')
    p.add_argument('--every', type=int, default=10,
                   help='frames between checkerboard views from a device or video')
    p.add_argument('--fleet', default=None, help='fleet YAML (colours, radii, start poses)')
    p.add_argument('--poses', type=float, nargs='+', default=None,
                   help='x y yaw_deg per robot in fleet order (default: the start poses '
                        'of config/hil.yaml, else of the fleet file)')
    p.add_argument('--tries', type=int, default=300,
                   help='frames to read from a device/video at most')
    p.add_argument('--save-image', default=None, help='also write the (last) frame used (PNG)')
    p.add_argument('--k1', type=float, default=0.0, help='--sim: radial distortion k1')
    p.add_argument('--k2', type=float, default=0.0, help='--sim: radial distortion k2')
    p.add_argument('--white-balance', type=float, nargs=3, default=(1.0, 1.0, 1.0),
                   metavar=('R', 'G', 'B'), help='--sim: channel gains of the camera')
    args = p.parse_args(argv)
    try:
        args.pattern = tuple(int(v) for v in args.board.lower().split('x'))
        if len(args.pattern) != 2 or min(args.pattern) < 2:
            raise ValueError
    except ValueError:
        p.error(f'--board {args.board}: give the inner corners as COLSxROWS, e.g. 9x6')
    return args


def _capture(source: str):
    capture = cv2.VideoCapture(int(source) if source.isdigit() else source)
    if not capture.isOpened():
        raise CalibrationError(f'cannot open camera {source}: check the device or file path')
    return capture


def grab(source: str, markers: ArenaMarkers, tries: int, lens: Lens | None = None
         ) -> np.ndarray:
    """A frame of ``source`` showing the markers (an image file, or the first of ``tries``
    device/video frames in which all four are found)."""
    if pathlib.Path(source).suffix.lower() in IMAGE_SUFFIXES:
        return read_image(source)
    capture = _capture(source)
    last = None
    try:
        for _ in range(max(1, tries)):
            ok, frame = capture.read()
            if not ok or frame is None:
                break
            last = frame
            try:
                calibrate(frame, markers, lens)
                return frame
            except CalibrationError:
                continue
    finally:
        capture.release()
    if last is None:
        raise CalibrationError(f'camera {source} gave no frame: is it in use or empty?')
    return last


def read_image(path: str) -> np.ndarray:
    image = cv2.imread(str(path))
    if image is None:
        raise CalibrationError(f'cannot read image {path}: check the path and format')
    return image


def board_views(sources: list[str], pattern: tuple[int, int], views: int, every: int,
                tries: int) -> tuple[list[np.ndarray], tuple[int, int], np.ndarray | None]:
    """Checkerboard corners found in image files, or in every ``every``-th frame of a
    device/video (up to ``views``); the image size and the last frame with a board."""
    found, size, last = [], None, None
    if all(pathlib.Path(s).suffix.lower() in IMAGE_SUFFIXES for s in sources):
        frames = (read_image(s) for s in sources)
    else:
        capture = _capture(sources[0])

        def frames():
            try:
                for i in range(max(1, tries)):
                    ok, frame = capture.read()
                    if not ok or frame is None:
                        return
                    if i % max(1, every) == 0:
                        yield frame
            finally:
                capture.release()
        frames = frames()
    for image in frames:
        h, w = image.shape[:2]
        if size is not None and size != (w, h):
            raise CalibrationError(f'the views differ in size ({size} and {(w, h)}); use '
                                   'one camera resolution')
        size = (w, h)
        corners = find_checkerboard(image, pattern)
        if corners is not None:
            found.append(corners)
            last = image
            if len(found) >= views:
                break
    if size is None:
        raise CalibrationError(f'{sources[0]} gave no frame: is it in use or empty?')
    return found, size, last


def sim_board_views(renderer, pattern: tuple[int, int], square: float, views: int,
                    seed: int = 0) -> list[np.ndarray]:
    """The synthetic lens's checkerboard views: the board tilted by up to 30 degrees at
    random places 0.45-0.7 m before the camera (covering the image)."""
    rng = np.random.default_rng(seed)
    out = []
    width, height = pattern[0] * square, pattern[1] * square
    for _ in range(20 * views):
        if len(out) >= views:
            break
        rvec = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5),
                         rng.uniform(-0.3, 0.3)])
        z = rng.uniform(0.45, 0.7)
        tvec = [rng.uniform(-0.45, 0.45) * z - width / 2,
                rng.uniform(-0.35, 0.35) * z - height / 2, z]
        corners = find_checkerboard(renderer.checkerboard(rvec, tvec, pattern, square),
                                    pattern)
        if corners is not None:
            out.append(corners)
    return out


def save_lens(path: str | pathlib.Path, lens: Lens, size: tuple[int, int]) -> None:
    """A calibration file holding the lens only (step 1; the arena step completes it)."""
    doc = {'image_size': [int(size[0]), int(size[1])],
           'lens': {'camera_matrix': [[float(v) for v in row] for row in lens.K],
                    'k1': float(lens.k1), 'k2': float(lens.k2),
                    'rms_error_px': float(lens.rms_px)}}
    pathlib.Path(path).write_text(
        '# Overhead camera calibration (swarm_bridge camera_calibrate): lens only; run '
        'camera_calibrate --source ... --out THIS_FILE for the arena next\n'
        + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))


def _existing(path: str) -> Calibration | None:
    """The calibration already in ``path`` (None if there is no file)."""
    if not pathlib.Path(path).exists():
        return None
    try:
        return Calibration.load(path, need_arena=False)
    except CalibrationError:
        raise CalibrationError(f'{path} exists but is not a calibration file; remove it or '
                               'choose another --out') from None


def run_lens(args: argparse.Namespace) -> str:
    if args.sim:
        from swarm_bridge.camera_render import CameraRenderer
        renderer = CameraRenderer(_sim_config(args))
        views = sim_board_views(renderer, args.pattern, args.square, args.views)
        size = (renderer.cfg.width, renderer.cfg.height)
    else:
        views, size, last = board_views(args.source, args.pattern, args.views, args.every,
                                        args.tries)
        if args.save_image and last is not None:
            cv2.imwrite(args.save_image, last)
    lens = calibrate_lens(views, size, args.pattern, args.square)
    save_lens(args.out, lens, size)
    return (f'{args.out} written: lens of {len(views)} checkerboard views, k1 {lens.k1:.4f}, '
            f'k2 {lens.k2:.4f}, focal {lens.K[0, 0]:.0f} px, corner residual '
            f'{lens.rms_px:.2f} px RMS; next: the arena (camera_calibrate --source ... '
            f'--out {args.out})')


def run_arena(args: argparse.Namespace, markers: ArenaMarkers) -> str:
    old = _existing(args.out)
    lens = old.lens if old is not None else None
    if args.sim:
        from swarm_bridge.camera_render import CameraRenderer
        image = CameraRenderer(_sim_config(args), markers=markers).render([])
    else:
        image = grab(args.source[0], markers, args.tries, lens)
    if args.save_image:
        cv2.imwrite(args.save_image, image)
    h, w = image.shape[:2]
    if old is not None and tuple(old.size) != (w, h):
        raise CalibrationError(f'{args.out} holds a lens for {old.size[0]}x{old.size[1]}, '
                               f'the camera gives {w}x{h}: calibrate the lens again '
                               '(--lens) at this resolution')
    cal = calibrate(image, markers, lens)
    if old is not None and 'homography_pixel_to_arena' in _doc(args.out):
        cal.white_balance, cal.cover_colors = old.white_balance, old.cover_colors
    cal.save(args.out)
    kept = ', lens ' + f'k1 {lens.k1:.4f}' if lens is not None else ''
    return (f'{args.out} written ({w}x{h} image, corner residual {cal.rms_m * 1000:.1f} mm '
            f'RMS{kept})')


def _doc(path: str) -> dict:
    doc = yaml.safe_load(pathlib.Path(path).read_text())
    return doc if isinstance(doc, dict) else {}


def demo_start_poses() -> list[float]:
    """The start poses of scripts/hil_demo.py: config/hil.yaml's ``initial_poses`` (x, y,
    yaw_deg per robot; ``[0.0]``, the fleet file's, when it has none)."""
    from swarm_common.paths import package_file
    try:
        doc = yaml.safe_load(package_file('swarm_bridge', 'config/hil.yaml').read_text())
        return [float(v) for v in doc['hil_world']['ros__parameters']['initial_poses']]
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):
        return [0.0]


def run_colors(args: argparse.Namespace) -> str:
    from swarm_bridge.camera_colors import measure_cover_colors
    from swarm_common.fleet import FleetError, initial_poses, load_fleet
    if not pathlib.Path(args.out).exists():
        raise CalibrationError(f'no calibration file {args.out}: calibrate the arena first '
                               f'(camera_calibrate --source ... --out {args.out})')
    cal = Calibration.load(args.out)
    try:
        robots = load_fleet(args.fleet)
        poses = initial_poses(args.poses or demo_start_poses(), robots)
    except (FleetError, OSError) as exc:
        raise CalibrationError(str(exc)) from None
    if args.sim:
        from swarm_bridge.camera_render import CameraRenderer, Cover
        from swarm_common.fleet import load_cover_colors
        printed = load_cover_colors(args.fleet)
        image = CameraRenderer(_sim_config(args), markers=cal.markers).render(
            [Cover(printed[r.color], r.radius, *p) for r, p in zip(robots, poses)])
    else:
        image = grab(args.source[0], cal.markers, args.tries, cal.lens)
    if args.save_image:
        cv2.imwrite(args.save_image, image)
    balance, colors = measure_cover_colors(image, cal, robots, poses)
    cal.white_balance, cal.cover_colors = balance, colors
    cal.save(args.out)
    table = ', '.join(f'{name} {list(rgb)}' for name, rgb in colors.items())
    return (f'{args.out} updated: white balance R G B x{balance[0]:.3f} x{balance[1]:.3f} '
            f'x{balance[2]:.3f}; cover colours {table}')


def _sim_config(args: argparse.Namespace):
    from swarm_bridge.camera_render import CameraConfig
    return CameraConfig(k1=args.k1, k2=args.k2, white_balance=tuple(args.white_balance))


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    markers = ArenaMarkers(side=args.marker_side) if args.corners is None else ArenaMarkers(
        centres=tuple(zip(args.corners[0::2], args.corners[1::2])), side=args.marker_side)
    if args.poses is not None and len(args.poses) % 3:
        print(f'camera_calibrate: --poses holds {len(args.poses)} numbers; give x y yaw_deg '
              'per robot', file=sys.stderr)
        return 2
    try:
        if args.lens:
            text = run_lens(args)
        elif args.colors:
            text = run_colors(args)
        else:
            text = run_arena(args, markers)
    except (CalibrationError, OSError, ValueError) as exc:
        print(f'camera_calibrate: {exc}', file=sys.stderr)
        return 2
    print(f'camera_calibrate: {text}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
