"""swarm_eval.equivalence (scripts/equivalence_study.py): the two-sample tests, Holm's
correction, missing and unsettled values, the loaders, the CLI and the worktree runner."""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from swarm_eval import equivalence

SEEDS = range(20)


def _trials(seed: int = 7, settling_shift: float = 0.0) -> list[dict]:
    """Twenty trials with values of the spread of the thesis scenario (50 agents)."""
    rng = np.random.default_rng(seed)
    trials, order = [], rng.permutation(len(SEEDS))
    for s in SEEDS:
        bound = 1600.0 + 80.0 * rng.standard_normal()
        trials.append({
            'seed': s, 'settled': True, 'displacement_lower_bound': bound,
            'total_displacement': bound * (1.01 + 0.005 * rng.random()),
            # values 1 s apart, shifted by distinct amounts: no ties in ranks or differences
            'settling_time': (120.0 + order[s] + 0.01 * rng.random()
                              + settling_shift * (1 + s / 100)),
            'epsilon_t': 0.4 + 0.1 * rng.standard_normal(),
            'epsilon_g': 0.07 + 0.005 * rng.standard_normal(),
            'assignment_agreement': 0.99 + 0.005 * rng.random(),
            'max_localization_error': 1.8 + 0.3 * rng.standard_normal(),
            'rms_localization_error': 0.3 + 0.03 * rng.standard_normal(),
            'wall_seconds': 45.0 + rng.random()})
    return trials


def _row(report: equivalence.Report, key: str) -> equivalence.MetricComparison:
    return next(r for r in report.rows if r.metric.key == key)


def test_identical_samples_are_the_same_with_p_one():
    trials = _trials()
    report = equivalence.compare(trials, [dict(t) for t in trials])
    tested = [r for r in report.rows if not r.metric.info]
    assert len(tested) == 8 and report.family_size == 3 * 8 and report.n_paired_seeds == 20
    for row in tested:
        assert (row.ks_p, row.mwu_p, row.wilcoxon_p) == pytest.approx((1.0, 1.0, 1.0))
        assert row.verdict == 'same' and row.relative_difference == 0.0
        assert row.n_before == row.n_after == row.n_pairs == 20
    assert _row(report, 'wall_seconds').verdict == 'info'
    assert report.differs == [] and not report.notes
    assert 'Verdict: every tested metric the same.' in equivalence.render(report)


def test_a_shifted_settling_time_differs_and_nothing_else_does():
    before = _trials()
    # 30-36 s later: every after value exceeds every before value (spread 20 s).
    after = _trials(settling_shift=30.0)
    report = equivalence.compare(before, after)
    row = _row(report, 'settling_time')
    # Disjoint samples of 20 and 20: D = 1, which 2 of the C(40, 20) orderings give.
    assert row.ks_p == pytest.approx(2 / math.comb(40, 20), rel=1e-9)
    # U = 0; the normal approximation with continuity correction (no ties).
    sigma = math.sqrt(20 * 20 * 41 / 12)
    assert row.mwu_p == pytest.approx(math.erfc((200 - 0.5) / sigma / math.sqrt(2)), rel=1e-6)
    # 20 positive paired differences: 2 of the 2^20 sign patterns are as extreme.
    assert row.wilcoxon_p == pytest.approx(2 / 2 ** 20, rel=1e-9)
    # Holm: the smallest of the 24 p-values is multiplied by 24.
    assert row.holm_p == pytest.approx(24 * 2 / math.comb(40, 20), rel=1e-9)
    assert 30.0 / 140 < row.relative_difference < 36.0 / 120
    assert report.differs == ['settling_time']
    assert 'Verdict: settling_time differs.' in equivalence.render(report)


def test_holm_adjusts_step_down_in_the_given_order():
    # sorted 0.01, 0.03, 0.04, 0.5 -> 4*0.01, 3*0.03, max(0.09, 2*0.04), 1*0.5
    assert equivalence.holm([0.01, 0.04, 0.03, 0.5]) == pytest.approx([0.04, 0.09, 0.09, 0.5])
    assert equivalence.holm([0.9, 0.8]) == pytest.approx([1.0, 1.0])
    assert equivalence.holm([]) == []


def test_holm_keeps_a_lone_small_p_from_deciding():
    # p = 0.01 would be rejected alone; in a family of 3 tests its Holm p is 0.03, and in
    # a family of 24 it is 0.24 and the metric is the same.
    assert equivalence.holm([0.01, 0.5, 0.5]) == pytest.approx([0.03, 1.0, 1.0])
    assert equivalence.holm([0.01] + [0.9] * 23)[0] == pytest.approx(0.24)


def test_an_unsettled_trial_is_counted_and_said_not_dropped_silently():
    before, after = _trials(), _trials()
    after[5].update(settled=False, settling_time=None)
    report = equivalence.compare(before, after)
    row = _row(report, 'settling_time')
    assert (row.n_before, row.n_after, row.n_pairs) == (20, 19, 19)
    assert row.verdict == 'same'
    assert report.notes == ['settling_time: 0 of 20 trials before and 1 of 20 after did not '
                            'settle (no settling time); its tests compare the settled trials '
                            'only']
    assert '- settling_time: 0 of 20 trials before and 1 of 20' in equivalence.render(report)


def test_a_metric_missing_on_one_side_is_not_compared_with_one_line():
    before, after = _trials(), _trials()
    for trial in after:
        del trial['rms_localization_error']
    report = equivalence.compare(before, after)
    row = _row(report, 'rms_localization_error')
    assert row.verdict == 'not compared' and row.ks_p is None and row.holm_p is None
    assert report.notes == ['rms_localization_error: missing in 0 of 20 trials before and 20 '
                            'of 20 after; not compared']
    assert report.family_size == 3 * 7
    assert '| RMS localization error [m] | 20 / 0 | ' in equivalence.render(report)


def test_displacement_ratio_is_derived_from_the_bound():
    trial = {'total_displacement': 1650.0, 'displacement_lower_bound': 1500.0}
    ratio = next(m for m in equivalence.METRICS if m.key == 'displacement_ratio')
    assert ratio.value(trial) == pytest.approx(1.1)
    assert ratio.value({'total_displacement': 1650.0, 'displacement_lower_bound': 0}) is None


def test_halves_split_at_the_median_seed():
    lower, upper = equivalence.halves(list(reversed(_trials())))
    assert [t['seed'] for t in lower] == list(range(10))
    assert [t['seed'] for t in upper] == list(range(10, 20))
    report = equivalence.compare(lower, upper)
    assert report.n_paired_seeds == 0
    assert all(r.wilcoxon_p is None for r in report.rows)


def test_bad_input_is_one_line(tmp_path: pathlib.Path):
    with pytest.raises(equivalence.EquivalenceError, match='not found; give an evaluate.py'):
        equivalence.load_trials(tmp_path / 'nowhere')
    (tmp_path / 'metrics.json').write_text('{"trials": [1, 2]}')
    with pytest.raises(equivalence.EquivalenceError, match='no list of per-trial metrics'):
        equivalence.load_trials(tmp_path)
    (tmp_path / 'metrics.json').write_text('{not json')
    with pytest.raises(equivalence.EquivalenceError, match='not evaluator output'):
        equivalence.load_trials(tmp_path)
    with pytest.raises(equivalence.EquivalenceError, match='alpha 2'):
        equivalence.compare(_trials(), _trials(), alpha=2.0)
    with pytest.raises(equivalence.EquivalenceError, match='no trials in after'):
        equivalence.compare(_trials(), [])


def _write_run(path: pathlib.Path, trials: list[dict], jsonl: bool = False) -> pathlib.Path:
    path.mkdir()
    if jsonl:
        (path / 'trials.jsonl').write_text(''.join(json.dumps(t) + '\n' for t in trials))
    else:
        (path / 'metrics.json').write_text(json.dumps({'trials': trials, 'mean': {}}))
    return path


def test_cli_compares_two_runs_and_writes_the_report(tmp_path: pathlib.Path, capsys):
    before = _write_run(tmp_path / 'before', _trials())
    after = _write_run(tmp_path / 'after', _trials(), jsonl=True)
    shifted = _write_run(tmp_path / 'shifted', _trials(settling_shift=30.0), jsonl=True)
    out = tmp_path / 'report.md'
    assert equivalence.main(['--before', str(before), '--after', str(after),
                             '--out', str(out)]) == 0
    text = out.read_text()
    assert 'seeds 0-19' in text and 'Verdict: every tested metric the same.' in text
    assert text == capsys.readouterr().out
    assert equivalence.main(['--before', str(before), '--after', str(shifted)]) == 1
    assert equivalence.main(['--before', str(before), '--halves']) == 0
    assert '(lower half)' in capsys.readouterr().out


def test_cli_bad_input_is_one_line_and_status_2(tmp_path: pathlib.Path, capsys):
    assert equivalence.main(['--before', str(tmp_path / 'none'), '--after', 'x']) == 2
    err = capsys.readouterr().err
    assert err.startswith('equivalence_study.py: ') and err.count('\n') == 1
    assert equivalence.main(['--before', str(tmp_path)]) == 2
    assert 'give --before DIR and --after DIR' in capsys.readouterr().err
    assert equivalence.main(['--run', 'HEAD']) == 2
    assert '--run needs --out DIR' in capsys.readouterr().err


FAKE_EVALUATE = """import json, os, pathlib, sys
out = pathlib.Path(sys.argv[sys.argv.index('--out') + 1])
(out / 'seen.json').write_text(json.dumps({'argv': sys.argv[1:], 'cwd': os.getcwd(),
    'pythonpath': os.environ['PYTHONPATH'].split(os.pathsep), 'script': __file__}))
"""


def _git(repo: pathlib.Path, *args: str) -> str:
    return subprocess.run(['git', '-C', str(repo), '-c', 'user.name=t', '-c',
                           'user.email=t@t', *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def test_run_at_revision_runs_that_commits_evaluator_in_a_removed_worktree(
        tmp_path: pathlib.Path):
    repo = tmp_path / 'repo'
    (repo / 'scripts').mkdir(parents=True)
    (repo / 'ros2_ws' / 'src' / 'swarm_x').mkdir(parents=True)
    (repo / 'ros2_ws' / 'src' / 'swarm_x' / 'marker').write_text('x')
    (repo / 'scripts' / 'evaluate.py').write_text(FAKE_EVALUATE)
    _git(repo, 'init', '-q')
    _git(repo, 'add', '.')
    _git(repo, 'commit', '-q', '-m', 'one')
    commit = _git(repo, 'rev-parse', 'HEAD')
    (repo / 'scripts' / 'evaluate.py').write_text('raise SystemExit(5)\n')   # uncommitted
    out = tmp_path / 'out'
    assert equivalence.run_at_revision('HEAD', 3, out, repo=repo, python=sys.executable) == 0
    seen = json.loads((out / 'seen.json').read_text())
    tree = pathlib.Path(seen['script']).parents[1]
    assert seen['argv'] == [*equivalence.EVALUATE_ARGS, '--trials', '3', '--out', str(out)]
    assert seen['pythonpath'][0] == str(tree / 'ros2_ws' / 'src' / 'swarm_x')
    assert (out / 'revision.txt').read_text() == commit + '\n'
    assert not tree.exists() and not tree.parent.exists()
    assert len(_git(repo, 'worktree', 'list').splitlines()) == 1
    with pytest.raises(equivalence.EquivalenceError, match='^git rev-parse --verify: '):
        equivalence.run_at_revision('no-such-rev', 3, out, repo=repo)
