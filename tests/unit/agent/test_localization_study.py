"""scripts/localization_study.py (thesis Figs. 4.4-4.6) runs end to end on a short trial."""

from __future__ import annotations

import json

import localization_study
import pytest


def test_study_writes_plot_and_summary(tmp_path, capsys):
    out = tmp_path / 'study'
    assert localization_study.main(['--periods', '3', '5', '--seeds', '1', '--duration', '12',
                                    '--agents', '2', '--out', str(out)]) == 0
    assert (out / 'error.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    summary = json.loads((out / 'summary.json').read_text())
    assert set(summary['periods']) == {'3', '5'}
    for stats in summary['periods'].values():
        assert {'max_error', 'rms_error'} <= set(stats)
        assert 0.0 < stats['rms_error'] <= stats['max_error']
        # trilateration against 8 beacons fuses many 2 m GPS fixes and 0.3 m ranges:
        # the agent's estimate stays well inside the thesis's 3 m tolerance
        assert stats['max_error'] < 3.0
        assert stats['misses'] == 0 and stats['mean_beacons_heard'] == 8
    printed = capsys.readouterr().out
    assert '"periods"' in printed and 'period 3 s: max error' in printed


def test_three_second_period_stays_within_one_and_a_half_metres():
    """The issue's target: a max error below 1.5 m at the thesis's 3 s period (the
    thesis reports below 3 m), over 5 seeds x 3 agents from the first fix on. It holds
    because the beacons start with the 2 m covariance of their first GPS fix and,
    parked, know they stand still (before both, the max was 1.53 m: the beacons'
    first 2 m GPS fix was trusted to 1 m)."""
    summary, _ = localization_study.study([3.0], seeds=5, duration=60.0, agents=3,
                                          imu_period=0.02)
    stats = summary['periods']['3']
    assert stats['max_error'] < 1.5, stats
    assert stats['rms_error'] < 0.5, stats


@pytest.mark.parametrize('args', [['--seeds', '0'], ['--duration', '2'], ['--periods', '-1']])
def test_bad_arguments_rejected(tmp_path, capsys, args):
    assert localization_study.main([*args, '--out', str(tmp_path)]) == 2
    assert 'localization_study: error:' in capsys.readouterr().err
