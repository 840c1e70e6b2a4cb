"""Camera calibration from the arena's four corner markers (thesis 5.1): the homography
maps pixels to metres to within a few millimetres; bad input fails in one line."""

from __future__ import annotations

import numpy as np
import pytest

from swarm_bridge.arena_calibration import (
    apply_homography,
    calibrate,
    Calibration,
    CalibrationError,
)
from swarm_bridge.camera_render import CameraConfig, CameraRenderer


@pytest.mark.parametrize('brightness,tilt,rotation', [(1.0, 0.04, 1.5), (0.4, 0.08, -3.0),
                                                       (1.3, 0.0, 0.0)])
def test_homography_from_the_markers_maps_pixels_to_the_arena(brightness, tilt, rotation):
    renderer = CameraRenderer(CameraConfig(brightness=brightness, tilt=tilt,
                                           rotation_deg=rotation, noise_std=3.0))
    cal = calibrate(renderer.render([]))
    grid = np.stack(np.meshgrid(np.linspace(-0.95, 0.95, 9), np.linspace(-0.95, 0.95, 9)),
                    axis=-1).reshape(-1, 2)
    pixels = apply_homography(renderer.H, grid)
    error = np.linalg.norm(cal.to_arena(pixels) - grid, axis=1)
    assert error.max() < 0.003, error.max()
    assert np.allclose(cal.to_pixels(cal.to_arena(pixels)), pixels, atol=1e-6)
    assert cal.rms_m < 0.01 and cal.size == (640, 480)   # corner residuals, below 1 cm


def test_calibration_file_round_trip(tmp_path):
    cal = calibrate(CameraRenderer().render([]))
    cal.save(tmp_path / 'cal.yaml')
    back = Calibration.load(tmp_path / 'cal.yaml')
    assert np.allclose(back.H, cal.H) and back.size == cal.size


def test_missing_markers_and_bad_files_are_named():
    blank = np.full((480, 640, 3), 128, np.uint8)
    with pytest.raises(CalibrationError, match=r'corner markers \[0, 1, 2, 3\] not found'):
        calibrate(blank)
    with pytest.raises(CalibrationError, match='run camera_calibrate first'):
        Calibration.load('/nonexistent/cal.yaml')
