"""scripts/shape_study.py and swarm_eval.shape_study: one row per shape and method, every
trial reported (refused, failed or not settled), with the table's cells."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shapely.geometry import box

from swarm_common.shapes import load_shape, shape_from_polygon, shape_json
from swarm_eval import shape_study_cli as shape_study
from swarm_eval.shape_study import (
    bearing_spread,
    markdown_table,
    row_metrics,
    run_trial,
    StudyTrial,
)
from swarm_mission.shape_gen import generate


def test_a_tiny_study_writes_one_row_per_shape_and_method(tmp_path):
    out = tmp_path / 'study'
    assert shape_study.main(['--shapes', '2', '--seed', '3', '--agents', '6', '--beacons',
                             '3', '--duration', '8', '--workers', '1', '--methods',
                             'bubble', 'forces', '--out', str(out)]) == 0
    study = json.loads((out / 'study.json').read_text())
    names = ['blob_3000', 'concave_3000']
    assert [(r['shape'], r['method']) for r in study['rows']] == [
        (n, m) for n in names for m in ('bubble', 'forces')]
    for name in names:
        per_shape = json.loads((out / f'{name}.json').read_text())
        assert [r['method'] for r in per_shape['rows']] == ['bubble', 'forces']
        # 8 s cannot settle a swarm scattered over +/-50 m: reported, with the agents.
        assert all(r['status'] == 'not settled' and r['diagnosis']['unsettled_agents']
                   for r in per_shape['rows'])
        for r in per_shape['rows']:
            # The diagnosis's path is the metric's total displacement (nobody died).
            assert r['diagnosis']['detours']['path_m'] == pytest.approx(
                r['metrics']['total_displacement'])
            assert r['diagnosis']['last_to_settle'] is None     # nobody settled for good
        table = (out / f'{name}.md').read_text().splitlines()
        rows = [line for line in table if line.startswith(f'| {name} |')]
        assert len(rows) == 2 and all('| not settled |' in line for line in rows)
        for row, line in zip(per_shape['rows'], rows):
            held = row['metrics'].get('settled')
            assert line.split(' | ')[3] == ('-' if held is None else 'yes' if held else 'no')
        # The shape file the ROS launcher reads is the same shape.
        shape = load_shape(str(out / 'shapes' / f'{name}.json'))
        assert shape.area == per_shape['area'] and shape_json(shape) == per_shape['geometry']
    assert study['summary']['bubble']['trials'] == 2
    assert study['summary']['forces']['not_settled'] == names


def test_a_shape_the_swarm_cannot_cover_is_a_row_with_the_reason():
    tiny = shape_from_polygon(box(0, 0, 2, 2), name='tiny')
    row = run_trial(StudyTrial(tiny, 'blob', 'bubble', duration_s=5.0))
    assert row['status'] == 'refused' and 'too small' in row['note']
    assert row['settled'] is None and row['metrics'] == {}


def test_a_trial_that_raises_is_a_row_with_the_error():
    shape = generate('blob', 0, 6)
    row = run_trial(StudyTrial(shape, 'blob', 'bubble', type_counts={1: 3, 2: 3},
                               n_beacons=9, duration_s=5.0))
    assert row['status'] == 'error' and '9 beacons' in row['note']


def test_missing_metric_keys_show_as_dashes():
    # A metrics dict without the newer keys: nothing invented, '-' in the table.
    old = {'total_displacement': 1060.0, 'displacement_lower_bound': 1000.0,
           'settling_time': 150.0, 'epsilon_t': 0.41}
    cells = row_metrics(old)
    assert cells['displacement_ratio'] == 1.06 and cells['settled'] is None
    assert cells['settling_ratio'] is None and cells['contacts'] is None
    line = markdown_table([{'shape': 's', 'method': 'bubble', 'status': 'settled',
                            'note': '', **cells}]).splitlines()[2]
    assert line == '| s | bubble | settled | - | - | 1.060 | 0.41 | - | - | - | - | - |  |'
    new = dict(old, settled=True, settling_time=150.0, least_settling_time=100.0,
               min_separation_ratio=math.inf, contacts=0)
    cells = row_metrics(new)
    assert (cells['settled'], cells['settling_ratio'], cells['contacts']) == (True, 1.5, 0)
    assert cells['min_separation_ratio'] == math.inf


def test_bearing_spread_is_the_smallest_sector_holding_every_beacon():
    here = np.array([5.0, 5.0])
    around = here + 10 * np.array([[1, 0], [0, 1], [-1, 0]])            # 0, 90, 180 deg
    assert bearing_spread(here, around) == pytest.approx(180.0)
    rad = np.radians([10.0, 20.0, 350.0])
    huddled = here + 20 * np.column_stack([np.cos(rad), np.sin(rad)])   # across 0 deg
    assert bearing_spread(here, huddled) == pytest.approx(30.0)
    assert bearing_spread(here, huddled[:1]) is None


def test_a_shape_the_mission_refuses_at_the_start_is_a_refused_row():
    # 90 x 8 m: four beacons with a 25 m radio cannot give every goal three.
    strip = shape_from_polygon(box(-45, -4, 45, 4), name='strip')
    row = run_trial(StudyTrial(strip, 'concave', 'bubble', n_beacons=4, duration_s=2.0))
    assert row['status'] == 'refused' and 'beacons' in row['note']
