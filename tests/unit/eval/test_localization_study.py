"""The localization study in the thesis scenario (swarm_eval.localization_study,
scripts/localization_study.py; thesis 4.2, Figs. 4.4-4.6)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from swarm_agent.localization import LocalizationConfig, Localizer, Mode
from swarm_eval import localization_study
from swarm_eval.localization_study import (
    FixProbe,
    steady_mask,
    study,
    StudyConfig,
    StudyError,
    THESIS_FIX_STD_M,
)
from swarm_sim.sensors import TrilaterationFixModel

RING = [np.array([10.0 * np.cos(a), 10.0 * np.sin(a)]) for a in (0.0, 2.1, 4.2)]


def test_thesis_fix_noise_is_2_m_per_axis():
    """Thesis 4.2: the fix is the true position plus N(0, 2 m) per axis. With n draws the
    sample standard deviation has a standard error of sigma / sqrt(2 n) (0.01 m) and the
    mean one of sigma / sqrt(n); both stay within four of them."""
    n = 20_000
    model = TrilaterationFixModel(np.random.default_rng(3))
    truth = np.array([4.0, -7.0])
    fixes = np.array([model.measure(truth)[0] for _ in range(n)])
    assert model.std == THESIS_FIX_STD_M == 2.0
    err = fixes - truth
    np.testing.assert_array_less(np.abs(err.std(axis=0) - 2.0), 4 * 2.0 / np.sqrt(2 * n))
    np.testing.assert_array_less(np.abs(err.mean(axis=0)), 4 * 2.0 / np.sqrt(n))
    assert abs(np.corrcoef(err.T)[0, 1]) < 4 / np.sqrt(n)   # independent axes


def _probe(fix_model):
    loc = Localizer(LocalizationConfig(), np.zeros(2))
    truth = np.array([0.5, -0.5])
    probe = FixProbe(loc, lambda: truth, fix_model)
    probe.install()
    return loc, probe, truth


def test_thesis_probe_fixes_with_three_beacons_and_misses_without():
    """With three beacon neighbours the thesis fix updates the filter; with fewer (or a
    beacon whose position is not finite) the tick is a miss: LOST, RETURN_HOME after
    three misses (3.1.3), NORMAL at the next fix."""
    loc, probe, truth = _probe(TrilaterationFixModel(np.random.default_rng(0)))
    heard = [(p, 10.0, 0.3) for p in RING]
    assert loc.localize(3.0, heard) == Mode.NORMAL
    assert probe.first_fix == 3.0 and probe.fixes == 1 and probe.pre_tick_errors == []
    assert not np.allclose(loc.position, 0.0)          # the 2 m fix moved the estimate
    bad = [(np.array([np.nan, 0.0]), 10.0, 0.3)] + heard[1:]
    modes = [loc.localize(3.0 * k, bad if k == 2 else heard[:2]) for k in (2, 3, 4)]
    assert modes == [Mode.LOST, Mode.LOST, Mode.RETURN_HOME]
    assert probe.misses == 3 and len(probe.pre_tick_errors) == 3
    assert loc.localize(15.0, heard) == Mode.NORMAL and probe.fixes == 2


def test_toa_probe_runs_the_localizers_own_trilateration():
    """Exact ranges to three beacons 10 m around: the fix is the truth with a covariance
    of about 0.06 m^2 per axis (0.3 m ranges), the prior 1 m^2, so the update leaves
    about 6 % of the prior's error."""
    loc, probe, truth = _probe(None)
    heard = [(p, float(np.hypot(*(p - truth))), 0.3) for p in RING]
    assert loc.localize(3.0, heard) == Mode.NORMAL
    assert probe.first_fix == 3.0 and probe.fixes == 1
    assert np.hypot(*(loc.position - truth)) < 0.1 * np.hypot(*truth)
    assert loc.localize(6.0, []) == Mode.LOST and probe.misses == 1


def test_steady_means_normal_for_the_last_three_periods():
    """An agent NORMAL from 0 to 10 s, LOST until 12 s, NORMAL again: with a 3 s period
    its samples are steady from 9 s to 10 s and again from 21 s (12 + 9) on."""
    times = np.arange(0.0, 30.0, 0.5)
    lost = (times > 10.0) & (times < 12.0)
    record = SimpleNamespace(times=times, modes=np.where(lost, Mode.LOST, Mode.NORMAL)[:, None],
                             alive=np.ones((len(times), 1), bool))
    mask = steady_mask(SimpleNamespace(record=record, agents=np.array([0]), period=3.0))
    assert list(times[mask[:, 0]]) == [9.0, 9.5, 10.0] + list(np.arange(21.0, 30.0, 0.5))


def _tiny(half_size: float) -> StudyConfig:
    return StudyConfig(agents=8, beacons=4, half_size=half_size)


@pytest.mark.parametrize('noise', ['thesis', 'toa'])
def test_study_in_range_reports_metrics_per_period(noise):
    """8 agents, 4 beacons, all deployed within 8 m of the shape (radio range 25 m):
    every agent fixes at every tick, none is ever LOST, and the statistics are ordered."""
    summary, curves = study([3.0, 5.0], noise, seeds=1, duration=12.0, config=_tiny(8.0))
    assert set(summary['periods']) == set(curves) == {'3', '5'}
    assert summary['noise'] == noise
    for key, stats in summary['periods'].items():
        assert stats['agents_never_fixed'] == 0 and stats['fix_share'] == 1.0, stats
        assert stats['lost_or_home_share'] == 0.0
        assert 0.0 < stats['rms_error'] <= stats['max_error'], stats
        assert 0.0 < stats['p95_error'] <= stats['max_error'], stats
        [worst] = stats['worst_per_trial']
        assert worst['seed'] == 0 and worst['error'] <= stats['max_error']
        times, err = curves[key]
        assert err.shape == (len(times), 4) and times[-1] == 12.0   # the whole duration
        assert np.all(np.isnan(err[times < float(key)]))   # nothing before the first fix


def test_study_out_of_range_agents_get_lost():
    """Deployed over +/-50 m with a 25 m radio, some agents start without three beacon
    neighbours: they are LOST or RETURN_HOME for part of the run."""
    summary, _ = study([3.0], 'thesis', seeds=1, duration=12.0, config=_tiny(50.0))
    stats = summary['periods']['3']
    assert stats['lost_or_home_share'] > 0.0 and stats['fix_share'] < 1.0, stats


def test_cli_writes_plot_and_summary(tmp_path, capsys):
    out = tmp_path / 'study'
    assert localization_study.main(['--periods', '3', '--seeds', '1', '--duration', '6',
                                    '--agents', '6', '--beacons', '3', '--noise', 'toa',
                                    '--out', str(out)]) == 0
    assert (out / 'error.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['noise'] == 'toa' and set(summary['periods']) == {'3'}
    assert 'period 3 s, toa: max error' in capsys.readouterr().out


@pytest.mark.parametrize('args', [['--seeds', '0'], ['--duration', '2'], ['--periods', '-1'],
                                  ['--beacons', '2'], ['--agents', '0'],
                                  ['--shape', 'no_such_shape']])
def test_bad_arguments_rejected(tmp_path, capsys, args):
    assert localization_study.main([*args, '--out', str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('localization_study: error:') and err.count('\n') == 1, err


def test_unknown_noise_profile_rejected():
    with pytest.raises(StudyError, match='unknown noise profile'):
        study([3.0], 'gps', seeds=1, duration=10.0)
