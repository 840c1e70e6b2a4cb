"""Statistical equivalence of two sets of evaluator trials (issue 23; docs/equivalence.md).

Judges whether a change of the brains changes what the thesis measures (chapter 4.3):
given the per-trial metrics of two ``evaluate.py --out`` directories (``before`` and
``after``, normally the same seeds at two commits), each metric is compared with

- the two-sample Kolmogorov-Smirnov test (any difference of the distributions) and the
  Mann-Whitney U test (a shift), two-sided, over all the trials of each side;
- the Wilcoxon signed-rank test over the paired differences of the seeds both sides ran
  (a trial depends only on its seed, so the same seed before and after is a pair);

and the medians of both sides with their relative difference. The verdict uses
``alpha`` (0.05) with Holm's step-down correction over every test of every tested
metric together (one family), so the chance of calling any unchanged metric "differs"
is at most ``alpha``; a metric differs when any of its tests is rejected. Wall seconds
are shown as information only and are not in the family. "same" means no difference
was detected, not that one was proven absent.

The metrics (``swarm_sim.metrics``, docs/metrics.md): total displacement (thesis 4.3.2)
and its ratio to the displacement lower bound, settling time (4.3.3, eq. 4.1 held),
epsilon_t (eq. 3.104) and epsilon_g (4.3.1), assignment agreement, and the maximum and
RMS localization error (4.2). A trial that did not settle has no settling time: it is
counted and reported on its own line, and the settling-time tests use the settled trials.

``run_at_revision`` measures a side at any commit: it runs the thesis scenario's
evaluator in a temporary git worktree of that commit with the same interpreter.

  scripts/env.sh python scripts/equivalence_study.py --run 0f6b150 --seeds 20 \\
      --out results/equivalence/before_0f6b150
  scripts/env.sh python scripts/equivalence_study.py \\
      --before results/equivalence/before_0f6b150 --after results/equivalence/after \\
      --out results/equivalence/report.md
  scripts/env.sh python scripts/equivalence_study.py \\
      --before results/equivalence/before_0f6b150 --halves

Exit status: 0 every tested metric the same, 1 some metric differs, 2 bad input.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np
from scipy import stats

ALPHA = 0.05
MIN_SAMPLES = 2   # values a side needs before a metric is tested
ROOT = pathlib.Path(__file__).resolve().parents[4]   # the checkout of a source tree
# The thesis scenario (4.3): bubble packing of the 314 m^2 circle by 50 agents.
EVALUATE_ARGS = ('--method', 'bubble', '--shape', 'circle_314', '--agents', '50',
                 '--seed', '0', '--workers', '1')
REVISION_FILE = 'revision.txt'   # written by run_at_revision: the full commit hash


class EquivalenceError(ValueError):
    """Input the study cannot use: one line saying why."""


@dataclass(frozen=True)
class Metric:
    """One compared quantity: a key of the trial metrics, or a value derived from them."""

    key: str
    label: str
    info: bool = False                       # shown, but not in the tested family
    derive: Callable[[Mapping], float | None] | None = None

    def value(self, trial: Mapping) -> float | None:
        """The metric of one trial; None when the trial has none."""
        v = self.derive(trial) if self.derive is not None else trial.get(self.key)
        if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        return float(v) if math.isfinite(v) else None


def _displacement_ratio(trial: Mapping) -> float | None:
    """Total displacement over its lower bound (docs/metrics.md)."""
    total, bound = trial.get('total_displacement'), trial.get('displacement_lower_bound')
    if total is None or not bound:
        return None
    return total / bound


METRICS = (
    Metric('total_displacement', 'total displacement [m]'),
    Metric('displacement_ratio', 'displacement / lower bound', derive=_displacement_ratio),
    Metric('settling_time', 'settling time [s]'),
    Metric('epsilon_t', 'eps_t'),
    Metric('epsilon_g', 'eps_g'),
    Metric('assignment_agreement', 'assignment agreement'),
    Metric('max_localization_error', 'max localization error [m]'),
    Metric('rms_localization_error', 'RMS localization error [m]'),
    Metric('wall_seconds', 'wall seconds (info only)', info=True),
)


@dataclass
class MetricComparison:
    """The tests of one metric; p-values are None where a test could not run."""

    metric: Metric
    n_before: int
    n_after: int
    median_before: float | None = None
    median_after: float | None = None
    ks_p: float | None = None
    mwu_p: float | None = None
    wilcoxon_p: float | None = None
    n_pairs: int = 0
    holm_p: float | None = None              # the smallest Holm-adjusted p of its tests
    verdict: str = 'not compared'            # 'same', 'differs', 'info', 'not compared'

    @property
    def relative_difference(self) -> float | None:
        """(median after - median before) / |median before|."""
        if self.median_before is None or self.median_after is None or not self.median_before:
            return None
        return (self.median_after - self.median_before) / abs(self.median_before)

    def p_values(self) -> list[float]:
        """The p-values of the tests that ran."""
        return [p for p in (self.ks_p, self.mwu_p, self.wilcoxon_p) if p is not None]


@dataclass
class Report:
    """Every metric's comparison, the notes on missing values, and what was compared."""

    before: str
    after: str
    rows: list[MetricComparison]
    notes: list[str] = field(default_factory=list)
    alpha: float = ALPHA
    n_before: int = 0
    n_after: int = 0
    n_paired_seeds: int = 0
    family_size: int = 0

    @property
    def differs(self) -> list[str]:
        """Keys of the metrics judged different."""
        return [r.metric.key for r in self.rows if r.verdict == 'differs']


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values (Holm 1979), in the order given.

    Sorted ascending, the i-th smallest (from 0) of m is multiplied by m - i, the running
    maximum is taken, and the result capped at 1; a test is rejected at ``alpha`` when its
    adjusted p is at most ``alpha``.
    """
    m = len(p_values)
    adjusted = [0.0] * m
    running = 0.0
    for rank, index in enumerate(sorted(range(m), key=lambda k: p_values[k])):
        running = max(running, min(1.0, (m - rank) * p_values[index]))
        adjusted[index] = running
    return adjusted


def _by_seed(trials: Iterable[Mapping], metric: Metric) -> tuple[dict, int]:
    """{seed or position: value} of the trials that carry the metric, and how many do not."""
    values, missing = {}, 0
    for position, trial in enumerate(trials):
        v = metric.value(trial)
        if v is None:
            missing += 1
        else:
            values[trial.get('seed', f'#{position}')] = v
    return values, missing


def _wilcoxon(before: Mapping, after: Mapping) -> tuple[float | None, int]:
    """Signed-rank p over the seeds both sides hold; 1.0 when every difference is zero."""
    common = [s for s in before if s in after and not str(s).startswith('#')]
    diffs = np.array([after[s] - before[s] for s in common])
    if len(diffs) < MIN_SAMPLES:
        return None, len(diffs)
    if not np.any(diffs):
        return 1.0, len(diffs)
    return float(stats.wilcoxon(diffs).pvalue), len(diffs)


def _missing_note(metric: Metric, labels: tuple[str, str], missing: tuple[int, int],
                  totals: tuple[int, int]) -> str | None:
    """The one line on trials without a value of ``metric`` (None when every trial has one)."""
    if not any(missing):
        return None
    counts = (f'{missing[0]} of {totals[0]} trials {labels[0]} and {missing[1]} of '
              f'{totals[1]} {labels[1]}')
    if metric.key == 'settling_time':
        return (f'settling_time: {counts} did not settle (no settling time); its tests '
                'compare the settled trials only')
    if any(m == t for m, t in zip(missing, totals)):
        return f'{metric.key}: missing in {counts}; not compared'
    return f'{metric.key}: no value in {counts}; compared over the rest'


def compare(before: Sequence[Mapping], after: Sequence[Mapping],
            metrics: Sequence[Metric] = METRICS, alpha: float = ALPHA,
            labels: tuple[str, str] = ('before', 'after')) -> Report:
    """Compare two sets of per-trial metric dicts metric by metric (module docstring)."""
    if not 0.0 < alpha < 1.0:
        raise EquivalenceError(f'alpha {alpha:g}: give a level in (0, 1), e.g. 0.05')
    if not before or not after:
        raise EquivalenceError(f'no trials in {labels[0] if not before else labels[1]}')
    totals = (len(before), len(after))
    report = Report(labels[0], labels[1], [], alpha=alpha, n_before=totals[0],
                    n_after=totals[1])
    seeds = [{t.get('seed') for t in side} - {None} for side in (before, after)]
    report.n_paired_seeds = len(seeds[0] & seeds[1])
    for metric in metrics:
        (b, miss_b), (a, miss_a) = _by_seed(before, metric), _by_seed(after, metric)
        row = MetricComparison(metric, len(b), len(a))
        note = _missing_note(metric, labels, (miss_b, miss_a), totals)
        if note:
            report.notes.append(note)
        if b:
            row.median_before = float(np.median(list(b.values())))
        if a:
            row.median_after = float(np.median(list(a.values())))
        if len(b) >= MIN_SAMPLES and len(a) >= MIN_SAMPLES:
            xb, xa = np.array(list(b.values())), np.array(list(a.values()))
            row.ks_p = float(stats.ks_2samp(xb, xa).pvalue)
            row.mwu_p = float(stats.mannwhitneyu(xb, xa, alternative='two-sided').pvalue)
            row.wilcoxon_p, row.n_pairs = _wilcoxon(b, a)
            row.verdict = 'info' if metric.info else ''
        elif b and a:
            report.notes.append(f'{metric.key}: {len(b)} and {len(a)} values; a test needs '
                                f'at least {MIN_SAMPLES} a side; not compared')
        report.rows.append(row)
    tested = [r for r in report.rows if r.verdict == '']
    family = [p for r in tested for p in r.p_values()]
    report.family_size = len(family)
    adjusted = iter(holm(family))
    for row in tested:
        row.holm_p = min(next(adjusted) for _ in row.p_values())
        row.verdict = 'differs' if row.holm_p <= alpha else 'same'
    return report


def _fmt(value: float | None, digits: int = 3) -> str:
    if value is None:
        return 'n/a'
    if value != 0 and (abs(value) < 10 ** -digits or abs(value) >= 10 ** 5):
        return f'{value:.2e}'
    return f'{value:.{digits}f}'


def render(report: Report) -> str:
    """The report as markdown: what was compared, how, the table and the notes."""
    lines = [f'Before: {report.before} ({report.n_before} trials). After: {report.after} '
             f'({report.n_after} trials). Paired seeds: {report.n_paired_seeds}.', '',
             'Two-sided two-sample Kolmogorov-Smirnov and Mann-Whitney U tests over all '
             'trials, Wilcoxon signed-rank over the paired seeds; verdict at alpha = '
             f"{report.alpha:g} with Holm's correction over all {report.family_size} tests "
             'of the tested metrics together (a metric differs when any of its tests is '
             'rejected; "same": no difference detected). Wall seconds: information only.',
             '', '| Metric | n before / after | Median before | Median after | Rel. diff | '
             'KS p | MWU p | Wilcoxon p (pairs) | Holm p | Verdict |',
             '|---|---|---|---|---|---|---|---|---|---|']
    for r in report.rows:
        rel = r.relative_difference
        lines.append(
            f'| {r.metric.label} | {r.n_before} / {r.n_after} | {_fmt(r.median_before)} | '
            f'{_fmt(r.median_after)} | {"n/a" if rel is None else f"{100 * rel:+.1f} %"} | '
            f'{_fmt(r.ks_p)} | {_fmt(r.mwu_p)} | {_fmt(r.wilcoxon_p)} ({r.n_pairs}) | '
            f'{_fmt(r.holm_p)} | {r.verdict} |')
    if report.notes:
        lines += ['', 'Notes:', *(f'- {note}' for note in report.notes)]
    differs = report.differs
    lines += ['', f'Verdict: {", ".join(differs)} differ{"s" if len(differs) == 1 else ""}.'
              if differs else 'Verdict: every tested metric the same.']
    return '\n'.join(lines) + '\n'


def load_trials(path: str | pathlib.Path) -> list[dict]:
    """The per-trial metrics of an ``evaluate.py --out`` directory: its metrics.json, or its
    trials.jsonl when the run did not finish; a .json/.jsonl file is read directly."""
    path = pathlib.Path(path)
    if path.is_dir():
        path = next((p for p in (path / 'metrics.json', path / 'trials.jsonl') if p.is_file()),
                    path / 'metrics.json')
    if not path.is_file():
        raise EquivalenceError(f'{path}: not found; give an evaluate.py --out directory '
                               '(metrics.json or trials.jsonl)')
    try:
        text = path.read_text(encoding='utf-8')
        if path.suffix == '.jsonl':
            trials = [json.loads(line) for line in text.splitlines() if line.strip()]
        else:
            trials = json.loads(text).get('trials')
    except (OSError, UnicodeDecodeError, ValueError, AttributeError) as exc:
        raise EquivalenceError(f'{path}: not evaluator output ({exc})') from None
    if not isinstance(trials, list) or not all(isinstance(t, dict) for t in trials):
        raise EquivalenceError(f'{path}: no list of per-trial metrics')
    return sorted(trials, key=lambda t: (t.get('seed') is None, t.get('seed') or 0))


def halves(trials: Sequence[Mapping]) -> tuple[list, list]:
    """The trials split at the median seed: the lower half of the seeds and the rest."""
    ordered = sorted(trials, key=lambda t: t.get('seed', 0))
    return list(ordered[:len(ordered) // 2]), list(ordered[len(ordered) // 2:])


def describe(path: pathlib.Path, trials: Sequence[Mapping]) -> str:
    """``path`` with its seeds and, when run_at_revision wrote it, its commit."""
    seeds = sorted(t['seed'] for t in trials if isinstance(t.get('seed'), int))
    span = f', seeds {seeds[0]}-{seeds[-1]}' if seeds else ''
    rev = path / REVISION_FILE if path.is_dir() else None
    commit = f' at {rev.read_text(encoding="utf-8").strip()[:12]}' if rev and rev.is_file() \
        else ''
    return f'{path}{commit}{span}'


def _git(repo: pathlib.Path, *args: str) -> str:
    done = subprocess.run(['git', '-C', str(repo), *args], capture_output=True, text=True,
                          check=False)
    if done.returncode:
        first = (done.stderr.strip().splitlines() or ['failed'])[0]
        raise EquivalenceError(f'git {" ".join(args[:2])}: {first}')
    return done.stdout.strip()


def run_at_revision(rev: str, seeds: int, out: str | pathlib.Path,
                    repo: pathlib.Path = ROOT, python: str = sys.executable,
                    evaluate_args: Sequence[str] = EVALUATE_ARGS) -> int:
    """Run the thesis scenario's evaluator (seeds 0..``seeds``-1) as of commit ``rev``.

    A detached git worktree of ``rev`` in a temporary directory; ``python`` runs its
    ``scripts/evaluate.py`` with PYTHONPATH led by its ``ros2_ws/src/swarm_*`` folders,
    so its packages (and their config files, ``swarm_common.paths``) are the ones
    imported; the worktree is removed afterwards. Writes ``out/revision.txt`` (the full
    hash) and returns the evaluator's exit status.
    """
    if seeds < 1:
        raise EquivalenceError(f'--seeds {seeds}: give at least 1')
    commit = _git(repo, 'rev-parse', '--verify', f'{rev}^{{commit}}')
    out = pathlib.Path(out).resolve()
    temp = pathlib.Path(tempfile.mkdtemp(prefix='equivalence_'))
    tree = temp / 'tree'
    try:
        _git(repo, 'worktree', 'add', '--detach', str(tree), commit)
        paths = sorted(str(p) for p in (tree / 'ros2_ws' / 'src').glob('swarm_*') if p.is_dir())
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [*paths, *filter(None, [os.environ.get('PYTHONPATH')])]))
        out.mkdir(parents=True, exist_ok=True)
        (out / REVISION_FILE).write_text(commit + '\n', encoding='utf-8')
        command = [python, str(tree / 'scripts' / 'evaluate.py'), *evaluate_args,
                   '--trials', str(seeds), '--out', str(out)]
        return subprocess.run(command, env=env, cwd=temp, check=False).returncode
    finally:
        subprocess.run(['git', '-C', str(repo), 'worktree', 'remove', '--force', str(tree)],
                       capture_output=True, check=False)
        shutil.rmtree(temp, ignore_errors=True)
        subprocess.run(['git', '-C', str(repo), 'worktree', 'prune'], capture_output=True,
                       check=False)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--before', metavar='DIR', help='evaluate.py --out directory')
    parser.add_argument('--after', metavar='DIR', help='evaluate.py --out directory')
    parser.add_argument('--halves', action='store_true',
                        help='compare --before with itself: the lower half of its seeds '
                             'against the upper half (a sanity check: expect "same")')
    parser.add_argument('--run', metavar='REV', help='run the thesis scenario at commit REV '
                        'into --out instead of comparing')
    parser.add_argument('--seeds', type=int, default=20, help='trials of --run (seeds 0..N-1)')
    parser.add_argument('--alpha', type=float, default=ALPHA)
    parser.add_argument('--out', default='', help='--run: results directory; otherwise the '
                        'markdown report file (the report is printed as well)')
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """``equivalence_study``: run one side at a commit, or compare two sides."""
    args = parse_args(argv)
    try:
        if args.run:
            if not args.out:
                raise EquivalenceError('--run needs --out DIR')
            return run_at_revision(args.run, args.seeds, args.out)
        if not args.before or not (args.after or args.halves):
            raise EquivalenceError('give --before DIR and --after DIR (or --halves), or --run')
        before = load_trials(args.before)
        where = pathlib.Path(args.before)
        if args.halves:
            lower, upper = halves(before)
            report = compare(lower, upper, alpha=args.alpha, labels=('lower', 'upper'))
            report.before = describe(where, lower) + ' (lower half)'
            report.after = describe(where, upper) + ' (upper half)'
        else:
            after = load_trials(args.after)
            report = compare(before, after, alpha=args.alpha)
            report.before = describe(where, before)
            report.after = describe(pathlib.Path(args.after), after)
    except EquivalenceError as exc:
        print(f'equivalence_study.py: {exc}', file=sys.stderr)
        return 2
    text = render(report)
    print(text, end='')
    if args.out:
        pathlib.Path(args.out).write_text(text, encoding='utf-8')
    return 1 if report.differs else 0
