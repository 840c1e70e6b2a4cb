"""benchmarks/bench_camera.py runs end to end in a tiny mode, so it cannot rot (its speed
is read from its printed figures, never asserted)."""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.mark.timeout(120)
def test_tiny_camera_benchmark_writes_its_figures(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / 'benchmarks' / 'bench_camera.py'),
                           '--frames', '3', '--brightness', '0.5,1.2', '--out', str(tmp_path)],
                          cwd=str(ROOT), capture_output=True, text=True, timeout=110)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = json.loads((tmp_path / 'bench_camera.json').read_text())
    assert [r['brightness'] for r in rows] == [0.5, 1.2]
    for row in rows:
        assert (row['robots'], row['width'], row['height']) == (5, 640, 480)
        for key in ('fps_median', 'fps_worst', 'render_fps', 'seconds_median'):
            assert math.isfinite(row[key]) and row[key] > 0, key
        assert row['found_fraction'] == 1.0 and row['position_rms_m'] < 0.01
        assert row['heading_rms_deg'] < 3.0
    assert proc.stdout.count('frames/s median') == 2
