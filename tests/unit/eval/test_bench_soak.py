"""swarm_eval.bench.soak: the soak's figures from first principles (the one-hour run
itself is not in CI: docs/soak.md)."""

from __future__ import annotations

import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from swarm_common.shapes import load_shape
from swarm_eval.bench import soak as probe


def test_the_process_tree_and_its_memory_and_cpu_come_from_proc():
    child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(30)'])
    try:
        tree = probe.descendants(os.getpid())
        assert os.getpid() in tree and child.pid in tree
        assert probe.label(child.pid) == f'{pathlib.Path(sys.executable).stem}[{child.pid}]'
        pss, uss = probe.memory(os.getpid())
        assert 1e6 < uss <= pss          # this Python holds numpy: MBs, some of them shared
        assert probe.cpu_seconds(os.getpid()) > 0.0
        pss_by, uss_by, cpu_by = probe.processes(os.getpid())
        assert probe.label(child.pid) in pss_by and child.pid in cpu_by
        assert all(uss_by[name] <= pss_by[name] for name in pss_by)
    finally:
        child.kill()
        child.wait()
    assert probe.memory(child.pid) is None and probe.cpu_seconds(child.pid) is None


def test_sim_time_is_read_from_the_launchers_progress_line():
    line = 't=  189.2 s  rtf=0.45  heard= 50/50  settled= 50  normal= 50  lost=  0'
    assert probe.sim_time(line) == 189.2
    assert probe.sim_time('launch_swarm: t=0.2 s sim loss = 0.05') is None


def test_growth_is_from_the_first_sample_after_the_warm_up_to_the_last_three():
    wall = [0, 300, 600, 900, 1200, 1500]
    pss = [50, 400, 500, 505, 510, 515]           # start-up, then +1 % a period
    assert math.isclose(probe.growth_percent(wall, pss, 600), (510 - 500) / 500 * 100)
    assert math.isnan(probe.growth_percent(wall, pss, 1500))   # one sample after


def test_real_time_factor_is_sim_over_wall_once_the_clock_runs():
    assert math.isclose(probe.rtf([0, 0, 10, 40], [0, 5, 10, 70]), 30 / 60)
    assert math.isnan(probe.rtf([0, 0], [0, 10]))


def test_settling_per_change_replays_eq_4_1_in_each_segment():
    """Two robots: inside the circle and still from t = 10 s of the first segment
    (settled after 10 s, hold 20 s); in the second they never stop."""
    shape = load_shape('circle_314')
    times = np.arange(0.0, 100.0, 0.5)
    n = len(times)
    inside = np.tile(np.array([[0.5, 0.0], [-0.5, 0.0]]) + shape.region.centroid.coords[0],
                     (n, 1, 1))
    positions = np.where(times[:, None, None] < 10.0, 100.0, inside)
    velocities = np.zeros((n, 2, 2))
    velocities[times >= 50.0] = 1.0
    record = {'times': times, 'positions': positions, 'velocities': velocities,
              'alive': np.ones((n, 2), dtype=bool)}
    got = probe.settling_per_change(record, [0.0, 50.0], [shape, shape], hold_s=20.0)
    assert got[0]['settled'] and got[0]['settling_time'] == 10.0
    assert not got[1]['settled'] and got[1]['settling_time'] is None
    assert got[1]['recorded_until'] == 99.5


def test_growth_by_process_names_each_process_present_since_the_warm_up():
    a = [10, 100, 100, 110, 110, 110]
    samples = [{'wall': 300 * k, 'pss': {'a': a[k], 'b': 50} if k else {'a': a[0]}}
               for k in range(6)]
    samples[-1]['pss']['c'] = 5           # started late: no growth to report
    assert probe.by_process_growth(samples, 'pss', 300) == {
        'a': pytest.approx(10.0), 'b': 0.0}
