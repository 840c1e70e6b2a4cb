#!/usr/bin/env python3
"""Frames per second of the overhead camera tracker (thesis 5.1): 5 robots at 640 x 480.

Renders ``--frames`` frames of the five robots of Table 5.1 moving in the arena
(swarm_bridge.camera_render, default synthetic camera: light gradient, blur, noise) at
each ``--brightness``, then times ``CameraTracker.update`` alone on them (rendering is
not counted; it is reported apart, as the hardware-in-the-loop world pays it). Prints one
line per brightness and writes bench_camera.json into --out when given. Issue 25's target:
at least 30 frames per second. ``--wide`` renders through a wide-angle lens (k1 -0.08,
k2 0.01) and a camera balanced for another light (R, G, B gains 0.8, 1.0, 1.25), and the
tracker works with the calibration of both (camera_calibrate --lens and --colors): the
per-frame cost of undistorting the circle centres and white-balancing the image.

  scripts/env.sh python benchmarks/bench_camera.py --frames 200
  scripts/env.sh python benchmarks/bench_camera.py --frames 200 --wide
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time

import numpy as np

from swarm_bridge.arena_calibration import calibrate, calibrate_lens
from swarm_bridge.camera_calibrate import sim_board_views
from swarm_bridge.camera_colors import measure_cover_colors
from swarm_bridge.camera_render import CameraConfig, CameraRenderer, Cover
from swarm_bridge.camera_tracker import CameraTracker
from swarm_common.fleet import load_cover_colors, load_fleet

WIDE = {'k1': -0.08, 'k2': 0.01, 'white_balance': (0.8, 1.0, 1.25)}


def bench(frames: int, brightness: float, width: int = 640, height: int = 480,
          wide: bool = False) -> dict:
    """Track ``frames`` rendered frames of 5 robots on circles; seconds per frame."""
    robots = load_fleet()
    colors = load_cover_colors()
    renderer = CameraRenderer(CameraConfig(width=width, height=height, brightness=brightness,
                                           noise_std=3.0, blur_sigma_px=1.0,
                                           **(WIDE if wide else {})))
    lens = None
    if wide:    # calibrated once, in the default light (noise 2, blur 0.9, brightness 1)
        setup = CameraRenderer(CameraConfig(width=width, height=height, **WIDE))
        lens = calibrate_lens(sim_board_views(setup, (9, 6), 0.03, 12), (width, height))
    else:
        setup = renderer
    calibration = calibrate(setup.render([]), lens=lens)
    if wide:
        start = [(r.x, r.y, r.yaw) for r in robots]
        calibration.white_balance, calibration.cover_colors = measure_cover_colors(
            setup.render([Cover(colors[r.color], r.radius, *p)
                             for r, p in zip(robots, start)]), calibration, robots, start)
    images, truth = [], []
    t0 = time.perf_counter()
    for f in range(frames):
        poses = []
        for i, _ in enumerate(robots):
            a = 2 * math.pi * i / len(robots) + 0.01 * f
            poses.append((0.55 * math.cos(a), 0.55 * math.sin(a), a + math.pi / 2))
        truth.append(poses)
        images.append(renderer.render([Cover(colors[r.color], r.radius, *p)
                                       for r, p in zip(robots, poses)]))
    render_s = (time.perf_counter() - t0) / frames
    tracker = CameraTracker(robots, colors, calibration, initial_poses={
        r.id: p[:2] for r, p in zip(robots, truth[0])})
    seconds, errors, turns, found = [], [], [], 0
    for f, image in enumerate(images):
        t = time.perf_counter()
        result = tracker.update(image, f / 30.0)
        seconds.append(time.perf_counter() - t)
        for r, (x, y, yaw) in zip(robots, truth[f]):
            if r.id in result.poses:
                found += 1
                px, py, pyaw = result.poses[r.id]
                errors.append(math.hypot(px - x, py - y))
                turns.append(math.degrees(math.remainder(pyaw - yaw, math.tau)))
    return {'robots': len(robots), 'width': width, 'height': height, 'frames': frames,
            'brightness': brightness, 'wide': wide, 'seconds_median': float(np.median(seconds)),
            'fps_median': float(1.0 / np.median(seconds)),
            'fps_worst': float(1.0 / np.max(seconds)),
            'render_fps': float(1.0 / render_s),
            'found_fraction': found / (frames * len(robots)),
            'position_rms_m': float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan,
            'heading_rms_deg': float(np.sqrt(np.mean(np.square(turns)))) if turns else math.nan}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--frames', type=int, default=200)
    parser.add_argument('--brightness', default='0.4,1.0,1.3',
                        help='comma-separated light levels')
    parser.add_argument('--wide', action='store_true',
                        help='wide-angle lens and shifted white balance, both calibrated')
    parser.add_argument('--out', default=None, help='directory for bench_camera.json')
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error('--frames must be at least 1')
    rows = []
    for level in (float(b) for b in args.brightness.split(',')):
        row = bench(args.frames, level, wide=args.wide)
        rows.append(row)
        print(f'{"wide lens, white balance: " if args.wide else ""}'
              f'brightness {level:.1f}: {row["fps_median"]:.1f} frames/s median '
              f'(worst frame {row["fps_worst"]:.1f}/s), {row["robots"]} robots at '
              f'{row["width"]}x{row["height"]}; found {row["found_fraction"]:.3f}, '
              f'position RMS {row["position_rms_m"] * 1000:.2f} mm, heading RMS '
              f'{row["heading_rms_deg"]:.2f} deg; rendering '
              f'{row["render_fps"]:.1f} frames/s', flush=True)
    if args.out:
        out = pathlib.Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / 'bench_camera.json').write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
