"""The Measured table (docs/measured.md): each row declared once, rendered from its runs' files.

A row (``Row``) says what it measures and holds its runs (``Run``): the exact command
(argv; ``{out}``: the run's directory under one results directory), the files it writes
there and the function that reads them into the run's part of the Result cell. No figure
is typed by hand: a run whose files are missing renders as "not measured".

  measure run --out results/measured [--rows faults,mesh] [--force] [--extra 'mesh=--seeds 2']
  measure render results/measured [--write docs/measured.md] [--from shapes30_seed100=DIR]

``run`` runs the rows' commands from the repository root one at a time, skipping a run
whose files exist (unless ``--force``), and leaves in each run's directory its output
(``measure.log``, or its own file for pytest and make) and ``measure.json``: argv, commit,
uncommitted changes to tracked files, date, wall time, exit code, cores, Python.
``--extra RUN=ARGS`` appends ARGS to a run's command (argparse keeps the last value:
``mesh=--seeds 2`` is a cheap mesh study); the page shows the command that really ran.
``--from RUN=DIR`` renders a run from another directory (an earlier study's --out).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping, Sequence
import contextlib
from dataclasses import dataclass
import datetime
import json
import math
import os
import pathlib
import platform
import re
import shlex
import statistics
import subprocess
import sys
import time

from swarm_eval.paths import repo_root

RECORD = 'measure.json'
NOT_MEASURED = 'not measured'
ENV = ('scripts/env.sh', 'python')


class OutputError(ValueError):
    """A run's files exist but do not hold what its row reads."""


@dataclass(frozen=True)
class Run:
    """One command of a row; ``name`` is its directory under the results directory."""

    name: str
    argv: tuple[str, ...]                     # '{out}' stands for the run's directory
    outputs: tuple[str, ...]                  # the files it writes: all there = measured
    read: Callable[[pathlib.Path], str]       # its part of the Result cell, from the files
    label: str = ''                           # names the part when a row has several runs
    stdout: str = ''                          # reports on stdout: kept in this file


@dataclass(frozen=True)
class Row:
    """One line of the table."""

    key: str
    what: str
    runs: tuple[Run, ...]
    cost: str = ''                            # what running it takes


def _json(path: pathlib.Path) -> dict:
    try:
        return json.loads(path.read_text(encoding='utf-8'))
    except (OSError, ValueError) as exc:
        raise OutputError(f'{path}: {exc}') from None


def _need(value, path: pathlib.Path, what: str):
    if not value:
        raise OutputError(f'{path}: no {what}')
    return value


def _f(value, digits: int) -> str:
    return '-' if value is None or not math.isfinite(value) else f'{value:.{digits}f}'


def _span(values: Sequence[float | None], digits: int) -> str:
    """'lo-hi' of the values (one value when both print alike)."""
    values = [v for v in values if v is not None and math.isfinite(v)]
    lo, hi = (_f(min(values), digits), _f(max(values), digits)) if values else ('-', '-')
    return lo if lo == hi else f'{lo}-{hi}'


def _median(values: Sequence[float | None]) -> float | None:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def _values(rows: Sequence[Mapping], key: str) -> list[float]:
    return [r[key] for r in rows if r.get(key) is not None]


def _hold(rows: Sequence[Mapping]) -> str:
    holds = {r.get('metrics', {}).get('settle_hold_s') for r in rows} - {None}
    return f' and held {_f(holds.pop(), 0)} s' if len(holds) == 1 else ''


def _unsettled(rows: Sequence[Mapping]) -> str:
    return ''.join(f'; {r["shape"]} {r["status"]}' + (f' ({r["note"]})' if r['note'] else '')
                   for r in rows if r['status'] != 'settled')


def shape_study_result(path: pathlib.Path, targets=(1.05, 1.10), loc_target=1.5) -> str:
    """A headless shape study (``shape_study_cli``), per method: what settled, displacement
    and settling ratios (the displacement targets, median and worst, judged), separation
    and the localization error after each agent's first fix."""
    study = _json(path / 'study.json')
    rows, parts = _need(study.get('rows'), path / 'study.json', 'rows'), []
    methods = [m for m in dict.fromkeys(r['method'] for r in rows) if '/ros' not in m]
    for method in methods:
        mine = [r for r in rows if r['method'] == method]
        disp, settle = _values(mine, 'displacement_ratio'), _values(mine, 'settling_ratio')
        loc = _values(mine, 'max_localization_error')
        med, worst = _median(disp), max(disp, default=None)
        met = med is not None and med <= targets[0] and worst <= targets[1]
        parts.append(
            (f'{method}: ' if len(methods) > 1 else '')
            + f'{sum(r["status"] == "settled" for r in mine)} of {len(mine)} settled'
            f'{_hold(mine)}; displacement / bound median {_f(med, 3)}, worst {_f(worst, 3)} '
            f'(targets {targets[0]:.2f} / {targets[1]:.2f}: {"met" if met else "missed"}); '
            f'settling / least settling median {_f(_median(settle), 2)}, worst '
            f'{_f(max(settle, default=None), 2)}; minimum separation '
            f'{_f(min(_values(mine, "min_separation_ratio"), default=None), 2)}, '
            f'{sum(_values(mine, "contacts"))} contacts; localization error after the first '
            'fix: p95 median '
            f'{_f(_median([r["metrics"].get("p95_localization_error") for r in mine]), 2)} m, '
            f'maximum median {_f(_median(loc), 2)} m, worst {_f(max(loc, default=None), 2)} m,'
            f' under {loc_target:g} m on {sum(v < loc_target for v in loc)} of {len(mine)}'
            + _unsettled(mine))
    args = study.get('arguments', {})
    head = f'{args["shapes"]} shapes, seed {args["seed"]}: ' if 'seed' in args else ''
    return head + ' / '.join(parts)


def ros_subset_result(path: pathlib.Path) -> str:
    """The ROS rows of a shape study run with --ros-subset, composed and per process."""
    study = _json(path / 'study.json')
    ros = _need([r for r in study.get('rows') or [] if '/ros-' in r['method']],
                path / 'study.json', 'ROS rows (run with --ros-subset)')
    modes = list(dict.fromkeys(r['method'] for r in ros))
    medians = ', '.join(
        f'{_f(_median(_values([r for r in ros if r["method"] == m], "settling_ratio")), 2)} '
        f'{m.split("ros-")[1].replace("-", " ")}' for m in modes)
    args = study.get('arguments', {})
    swarm = (f'{args["ros_agents"]} agents, {args["ros_beacons"]} beacons; '
             if 'ros_agents' in args else '')
    return (f'{swarm}{sum(r["status"] == "settled" for r in ros)} of {len(ros)} runs settled'
            f'{_hold(ros)} ({len({r["shape"] for r in ros})} shapes x {len(modes)} modes); '
            f'settling {_span(_values(ros, "settling_ratio"), 2)} x the least settling time '
            f'(median {medians}); displacement {_span(_values(ros, "displacement_ratio"), 3)}'
            f' x the bound; minimum separation '
            f'{_span(_values(ros, "min_separation_ratio"), 2)}, '
            f'{sum(_values(ros, "contacts"))} contacts; agreement '
            f'{_span(_values(ros, "assignment_agreement"), 2)}; maximum localization error '
            f'after the first fix {_span(_values(ros, "max_localization_error"), 2)} m'
            + _unsettled(ros))


def evaluate_result(path: pathlib.Path) -> str:
    """``evaluate``'s metrics.json: every trial's figures, joined with ' / '."""
    trials = _need(_json(path / 'metrics.json').get('trials'), path / 'metrics.json', 'trials')

    def each(key: str, digits: int) -> str:
        return ' / '.join(_f(t.get(key), digits) for t in trials)

    settled = sum(bool(t.get('settled')) for t in trials)
    who = (('both' if len(trials) == 2 else f'all {len(trials)}') if settled == len(trials)
           else f'{settled} of {len(trials)}')
    finals = {t.get('duplicate_goal_claims_final') for t in trials}
    ratio = ' / '.join(_f(t['total_displacement'] / t['displacement_lower_bound']
                          if t.get('displacement_lower_bound') else None, 3) for t in trials)
    return (f'seeds {", ".join(str(t.get("seed")) for t in trials)}: {who} settled and held:'
            f' {each("settling_time", 1)} s, {each("settling_ratio", 2)} x the least settling'
            f' time ({each("least_settling_time", 1)} s), {each("redepartures", 0)} '
            f're-departures; displacement {ratio} x the bound; minimum separation '
            f'{each("min_separation_ratio", 2)}, {sum(_values(trials, "contacts"))} contacts;'
            f' agreement {each("assignment_agreement", 3)}; goals claimed twice: '
            + (f'{finals.pop()}' if len(finals) == 1 else each('duplicate_goal_claims_final', 0))
            + f' at the end, up to {each("duplicate_goal_claims_peak", 0)} at once on the way '
            f'({each("duplicate_goal_claims_integral", 0)} goal-seconds); localization p95 '
            f'{each("p95_localization_error", 2)} m, RMS {each("rms_localization_error", 2)} '
            f'm, max {each("max_localization_error", 1)} m')


def localization_result(path: pathlib.Path) -> str:
    """``localization_study``'s summary.json: max, p95 and RMS per localization period."""
    s = _json(path / 'summary.json')
    periods = _need(s.get('periods'), path / 'summary.json', 'periods')
    keys = list(periods)

    def each(key: str, digits: int) -> str:
        return ' / '.join(_f(periods[k].get(key), digits) for k in keys)

    bounds = s.get('thesis_max_error_m') or {}
    thesis = (f' (thesis: below {" / ".join(_f(bounds[k], 0) for k in keys)} m)'
              if all(k in bounds for k in keys) else '')
    return (f'periods {" / ".join(keys)} s, {s.get("seeds")} seeds x '
            f'{_f(s.get("duration_s"), 0)} s: max {each("max_error", 1)} m '
            f'({_span([periods[k].get("steady_max_error") for k in keys], 1)} m for agents '
            f'NORMAL three periods), p95 {each("p95_error", 2)} m, RMS '
            f'{_span([periods[k].get("rms_error") for k in keys], 2)} m{thesis}')


def dsdv_result(path: pathlib.Path) -> str:
    """bench_dsdv.json: periods to converge after a link break, mean (worst), per size and
    loss; routing traffic per agent."""
    data = _json(path / 'bench_dsdv.json')
    table = _need(data.get('table'), path / 'bench_dsdv.json', 'table')
    sizes = list(dict.fromkeys(r['agents'] for r in table))

    def cell(r: Mapping) -> str:
        mean, worst = r['link_break_mean_periods'], r['link_break_worst_periods']
        missed = r['link_break_not_converged']
        if mean is None:
            return f'none of {r["seeds"]} converged'
        return (f'{mean:.1f}' + (f' ({worst:.2f})' if worst is not None else '')
                + (f', {missed} of {r["seeds"]} not converged' if missed else ''))

    per_size = '; '.join(f'{n} agents ' + ' / '.join(cell(r) for r in table if r['agents'] == n)
                         for n in sizes)
    traffic = ', '.join(_span([r['routing_bytes_per_s_per_agent'] for r in table
                               if r['agents'] == n], 0) + f' B/s at {n} agents' for n in sizes)
    losses = ' / '.join(f'{100 * r["loss"]:.0f}' for r in table if r['agents'] == sizes[0])
    return (f'loss {losses} %, periods ({_f(data.get("period_s"), 0)} s) to converge after a '
            f'link break, mean (worst): {per_size}; routing traffic per agent {traffic}')


def fault_result(path: pathlib.Path) -> str:
    """faults.json: trials settled and passed; per case the recovery after the last fault."""
    data = _json(path / 'faults.json')
    cases = _need(data.get('cases'), path / 'faults.json', 'cases')
    trials = data.get('trials') or []
    parts = []
    for name, case in cases.items():
        mine = [t for t in trials if t.get('case') == name] or [{}]
        gone = _median([t['agents'] - t['agents_alive'] for t in mine
                        if t.get('agents') is not None and t.get('agents_alive') is not None])
        kind, value = mine[0].get('kind'), mine[0].get('value')
        what = (f'{gone:g} of {mine[0].get("agents")} agents killed' if kind == 'kill' and gone
                else f'{gone:g} beacon{"s" * (gone != 1)} removed' if kind == 'beacons' and gone
                else 'no fault: the settling time' if kind == 'loss' and not value else '')
        parts.append(f'{name} {_f(case.get("recovery_time"), 1)} s'
                     + (f' ({what})' if what else ''))
    return (f'{data.get("config", {}).get("agents", "?")} agents: '
            f'{sum(bool(t.get("settled")) for t in trials)} of {len(trials)} trials settled, '
            f'{sum(bool(t.get("passed")) for t in trials)} passed; recovery after the fault: '
            + ', '.join(parts))


def hil_result(path: pathlib.Path) -> str:
    """hil.json: per shape eq. 5.4's settling time, arrival time and final goal error."""
    out = []
    for r in _need(_json(path / 'hil.json').get('results'), path / 'hil.json', 'results'):
        far, at, st = (max(r.get('final_goal_error') or [math.nan]), r.get('arrival_time'),
                       r.get('settling_time'))
        when = f'settled at {st:.1f} s' if st is not None else str(r.get('outcome'))
        when += ('' if 'arrival_time' not in r else ', not arrived' if at is None
                 else f', arrived at {at:.1f} s')
        out.append(f'{r["shape"]} {when}, every robot within {_f(100 * far, 1)} cm of its goal'
                   f' (displacement {_f(r.get("total_displacement"), 2)} m, bound '
                   f'{_f(r.get("displacement_lower_bound"), 2)} m)')
    return '; '.join(out)


def mesh_result(path: pathlib.Path, shapes=('circle_314', 'thesis_shape_1', 'thesis_shape_2',
                                             'thesis_shape_3', 'thesis_shape_4')) -> str:
    """mesh_study.json: eps_t / eps_g of bubble packing, mean (worst seed), and the range of
    the fractals' means, over the thesis shapes."""
    data = _json(path / 'mesh_study.json')
    shapes = _need([s for s in shapes if s in data], path / 'mesh_study.json', 'thesis shape')

    def mean_worst(stats: Mapping, digits: int) -> str:
        mean, worst = _f(stats['mean'], digits), _f(stats['max'], digits)
        return mean if mean == worst else f'{mean} ({worst})'

    bubble = ', '.join(f'{s} {mean_worst(data[s]["bubble"]["epsilon_t"], 2)} / '
                       f'{mean_worst(data[s]["bubble"]["epsilon_g"], 3)}' for s in shapes)
    fractal = [data[s]['fractal'] for s in shapes if 'fractal' in data[s]]
    return (f'{data[shapes[0]]["bubble"].get("runs")} seeds; bubble packing eps_t / eps_g, '
            f'mean (worst seed): {bubble}; fractals '
            f'{_span([f["epsilon_t"]["mean"] for f in fractal], 2)} / '
            f'{_span([f["epsilon_g"]["mean"] for f in fractal], 2)}')


def _text(path: pathlib.Path) -> str:
    try:
        return path.read_text(encoding='utf-8', errors='replace')
    except OSError as exc:
        raise OutputError(f'{path}: {exc}') from None


def pytest_summary(path: pathlib.Path) -> str:
    """pytest's closing line in the saved output: '9 passed in 81.20s (0:01:21)'."""
    found = re.findall(r'^=*\s*((?:\d+ \w+(?:, )?)+ in [\d.]+s(?: \([^)]*\))?)\s*=*$',
                       _text(path / 'pytest.txt'), re.M)
    return _need(found, path / 'pytest.txt', 'pytest summary line')[-1]


def crlb_result(path: pathlib.Path) -> str:
    """The Monte Carlo test's printed ratio and its acceptance band (4 standard errors)."""
    m = _need(re.search(r'RMS error / sqrt\(CRLB\) = ([\d.]+) \+/- ([\d.]+) \(n=(\d+)',
                        _text(path / 'pytest.txt')),
              path / 'pytest.txt', '"RMS error / sqrt(CRLB)" line (pytest -s prints it)')
    return (f'RMS error / sqrt(CRLB) = {float(m[1]):.3f} over {m[3]} fixes (accepted: 1 +/- 4 '
            f'standard errors, {4 * float(m[2]):.3f}); {pytest_summary(path)}')


def firmware_result(path: pathlib.Path) -> str:
    """firmware/tools/memory_report.py's lines in the build's output."""
    text = _text(path / 'make.txt')
    flash = re.search(r'flash:\s*(\d+) of (\d+) words', text)
    ram = _need(flash and re.search(r'RAM:\s*(\d+) of (\d+) bytes', text), path / 'make.txt',
                'flash and RAM report (did the build fail?)')
    return (f'{flash[1]} / {flash[2]} flash words, {ram[1]} / {ram[2]} RAM bytes (general '
            'purpose registers)')


def _cmd(name: str, script: str, args: str, outputs: tuple[str, ...],
         read: Callable[[pathlib.Path], str], label: str = '') -> Run:
    return Run(name, (*ENV, script, *args.split(), '--out', '{out}'), outputs, read, label)


def _pytest(name: str, args: str, read: Callable[[pathlib.Path], str]) -> Run:
    return Run(name, (*ENV, '-m', 'pytest', *args.split()), ('pytest.txt',), read,
               stdout='pytest.txt')


def _study(name: str, args: str, read=shape_study_result) -> Run:
    return _cmd(name, 'scripts/shape_study.py', args, ('study.json',), read)


def _loc(noise: str, label: str) -> Run:
    return _cmd(f'localization_{noise}', 'scripts/localization_study.py', '--periods 3 5 8 '
                f'--seeds 3 --duration 200 --noise {noise}', ('summary.json',),
                localization_result, label)


def _hil(name: str, extra: str = '', label: str = '') -> Run:
    return _cmd(name, 'scripts/hil_demo.py', '--shape hw_square --duration 100 --settle-hold 2'
                f' {extra}', ('hil.json',), hil_result, label)


ROWS: tuple[Row, ...] = (
    Row('shapes30', 'Shapes nobody tuned for: 30 generated shapes (blobs, concave, spiral, '
        'holes, 2 m necks, obstacles between start and shape), thesis scenario (50 agents, 8 '
        'beacons, 20/20/10), bubble, headless (`docs/shape_study.md`); seed 200 was not '
        'looked at while tuning',
        (_study('shapes30_seed100', '--shapes 30 --seed 100 --methods bubble --workers 2'),
         _study('shapes30_seed200', '--shapes 30 --seed 200 --methods bubble --workers 2')),
        'about 1 h each on 2 cores'),
    Row('shapes_ros', 'The same shapes through ROS, 16 agents, 4 beacons, sized to 100 m^2, '
        'composed and one process per agent',
        (_study('shapes_ros', '--shapes 5 --seed 100 --methods bubble --ros-subset 5',
                ros_subset_result),), 'about 1 h: 10 ROS runs one at a time'),
    Row('thesis', 'Thesis scenario (circle_314), headless, seeds 0 and 1',
        (_cmd('thesis', 'scripts/evaluate.py', '--method bubble --shape circle_314 --agents '
              '50 --trials 2 --workers 1 --duration 400', ('metrics.json',), evaluate_result),),
        'about 2 min'),
    Row('chevron', 'A long concave shape (20 m x 38 m chevron, 7 vertices) with 16 agents and '
        '4 beacons, headless: the case where goals lie out of reach of three beacons',
        (_pytest('chevron', 'tests/unit/sim/test_beacon_goals_headless.py -q',
                 pytest_summary),), 'about 1 min'),
    Row('localization', 'Localization in the thesis scenario (Figs. 4.4-4.6), 8 moving '
        'beacons, 25 m radio, periods 3 / 5 / 8 s, 3 seeds x 200 s (`docs/localization.md`)',
        (_loc('thesis', 'thesis noise (2 m on the fix)'),
         _loc('toa', "the system's TOA ranges")), 'about 30 min each'),
    Row('dsdv', 'DSDV convergence, 5 seeds, loss 0 / 10 / 30 %',
        (_cmd('dsdv', 'benchmarks/bench_dsdv.py', '--agents 50,100 --loss 0,0.1,0.3 --seeds 5',
              ('bench_dsdv.json',), dsdv_result),),
        'about 10 min; 200 agents at 30 % loss take about 15 min a seed'),
    Row('faults', 'Fault study, quick (6 agents), headless',
        (_cmd('faults', 'scripts/fault_study.py', '--quick --cases loss_0,kill_30,beacons_one',
              ('faults.json',), fault_result),), 'about 1 min'),
    Row('hil', 'HIL, five emulated PIC16F690 robots through `bridge_node`, frames through the '
        'lossy radio medium',
        (_hil('hil'), _hil('hil_loss', '--radio-loss 0.2', 'with --radio-loss 0.2')),
        'about 2 min each, ROS processes'),
    Row('e2e', 'e2e layer (formation, self-repair, two hosts in network namespaces, HIL, a '
        'killed launcher leaves no process)', (_pytest('e2e', '-m e2e', pytest_summary),),
        'about 15 min'),
    Row('firmware', 'Firmware size on the PIC16F690 (needs `make toolchain`: sdcc with only '
        'the pic14 port, built into ~/.cache/swarm-formation/sdcc-pic, about 2 min cold)',
        (Run('firmware', ('bash', '-c', 'make toolchain && make -C firmware pic'),
             ('make.txt',), firmware_result, stdout='make.txt'),),
        'seconds once the toolchain is built'),
    Row('mesh', 'Mesh quality, 50 agents 20:20:10, partitions only',
        (_cmd('mesh', 'scripts/mesh_study.py', '--seeds 20', ('mesh_study.json',),
              mesh_result),), 'about 1 min'),
    Row('crlb', 'Trilateration vs Cramer-Rao',
        (_pytest('crlb', 'tests/unit/agent/test_localization.py::'
                 'test_monte_carlo_error_reaches_the_crlb -q -s', crlb_result),), 'seconds'),
)
RUNS = {run.name: run for row in ROWS for run in row.runs}


def select(keys: str) -> list[Row]:
    """The rows named in ``keys`` (comma separated; '' is every row)."""
    known = {row.key: row for row in ROWS}
    if unknown := [k for k in keys.split(',') if k and k not in known]:
        raise ValueError(f'--rows {",".join(unknown)}: unknown row; the rows are '
                         f'{",".join(known)}')
    return [known[k] for k in keys.split(',')] if keys else list(ROWS)


def command(argv: Sequence[str], out: pathlib.Path | str) -> list[str]:
    return [str(out) if a == '{out}' else a for a in argv]


def measured(run: Run, path: pathlib.Path) -> bool:
    return all((path / f).is_file() for f in run.outputs)


def git(*args: str) -> str:
    try:
        return subprocess.run(['git', *args], cwd=repo_root(), capture_output=True, text=True,
                              timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ''


def run_one(run: Run, out: pathlib.Path, extra: Sequence[str] = ()) -> int:
    """Run one command into ``out/<run.name>``; leave its record and its output there."""
    path = out / run.name
    path.mkdir(parents=True, exist_ok=True)
    where = path.resolve()      # the command runs in the repository: relative to it there
    where = where.relative_to(repo_root()) if where.is_relative_to(repo_root()) else where
    argv = command(run.argv, where) + list(extra)
    print(f'measure: {run.name}: {shlex.join(argv)}', flush=True)
    record = {'argv': argv, 'extra': list(extra), 'commit': git('rev-parse', 'HEAD'),
              'dirty': git('status', '--porcelain', '--untracked-files=no').splitlines(),
              'started': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}
    t0 = time.monotonic()
    with open(path / (run.stdout or 'measure.log'), 'wb') as log:
        proc = subprocess.Popen(argv, cwd=repo_root(), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT)
        for chunk in iter(lambda: proc.stdout.read1(4096), b''):
            log.write(chunk)
            sys.stdout.buffer.write(chunk)
            sys.stdout.flush()
        code = proc.wait()
    record.update(wall_s=round(time.monotonic() - t0, 1), returncode=code,
                  cores=os.cpu_count(), python=platform.python_version())
    (path / RECORD).write_text(json.dumps(record, indent=2) + '\n', encoding='utf-8')
    print(f'measure: {run.name}: exit {code} after {record["wall_s"]:.0f} s -> {path}', flush=True)
    return code


def run_rows(rows: Sequence[Row], out: pathlib.Path, force: bool = False,
             extra: Mapping[str, Sequence[str]] | None = None) -> int:
    """Run every run of ``rows`` whose files are missing (all with ``force``)."""
    failed = 0
    for run in (run for row in rows for run in row.runs):
        if measured(run, out / run.name) and not force:
            print(f'measure: {run.name}: outputs exist in {out / run.name}, skipped (--force '
                  'runs it again)', flush=True)
            continue
        failed += run_one(run, out, (extra or {}).get(run.name, ())) != 0
    return 1 if failed else 0


def _record(path: pathlib.Path) -> dict | None:
    with contextlib.suppress(OutputError):
        return _json(path / RECORD)
    return None


def provenance(run: Run, path: pathlib.Path) -> str:
    """Where a run's figures come from: its record, else the command its files name."""
    if not measured(run, path):
        return f'`{run.name}`: {NOT_MEASURED}'
    if rec := _record(path):
        changed = rec.get('dirty')      # the tracked files changed when it started
        count = f' to {len(changed)} files ({RECORD} names them)' \
            if isinstance(changed, list) else ''
        dirty = f' with uncommitted changes{count}' if changed else ''
        return (f'`{run.name}`: commit `{rec.get("commit", "")[:12] or "unknown"}`{dirty}, '
                f'{rec.get("started")}, {rec.get("wall_s")} s wall, exit '
                f'{rec.get("returncode")}, {rec.get("cores")} cores, Python {rec.get("python")}'
                f' ({path})')
    named = recorded_command(run, path)
    named = f'; the files name the command `{named}`' if named else ''
    return f'`{run.name}`: files in {path}, no run record (commit not recorded){named}'


def shown_command(run: Run, path: pathlib.Path) -> str:
    """The command as it ran (its record), else as declared with its directory."""
    rec = (_record(path) if measured(run, path) else None) or {}
    return shlex.join(rec.get('argv') or command(run.argv, path))


def recorded_command(run: Run, path: pathlib.Path) -> str:
    """The command a run's JSON files name (hil.json and faults.json keep theirs)."""
    for name in (n for n in run.outputs if n.endswith('.json')):
        with contextlib.suppress(OutputError):
            if isinstance(named := _json(path / name).get('command'), str):
                return named
    return ''


def result_cell(row: Row, dirs: Mapping[str, pathlib.Path]) -> str:
    """The Result cell: each measured run's part, "not measured" for the others."""
    if not any(measured(run, dirs[run.name]) for run in row.runs):
        return NOT_MEASURED
    parts = []
    for run in row.runs:
        try:
            part = run.read(dirs[run.name]) if measured(run, dirs[run.name]) else NOT_MEASURED
        except (OutputError, KeyError, TypeError, ValueError) as exc:
            part = f'{NOT_MEASURED}: files unreadable ({type(exc).__name__}: {exc})'
        parts.append(f'{run.label}: {part}' if run.label else part)
    return '<br>'.join(parts)


def render(out: pathlib.Path, sources: Mapping[str, pathlib.Path] | None = None,
           rows: Sequence[Row] = ROWS, now: datetime.datetime | None = None) -> str:
    """docs/measured.md from the results directory ``out``."""
    dirs = {name: (sources or {}).get(name, out / name) for name in RUNS}
    now = now or datetime.datetime.now(datetime.UTC)
    froms = ''.join(f' --from {k}={v}' for k, v in (sources or {}).items())
    lines = ['# Measured', '', 'Generated by `scripts/env.sh python scripts/measure.py render '
             f'{out}{froms}` from the files the commands below wrote (`measure run` runs them):'
             f' no figure on this page is typed by hand; a run without files is "{NOT_MEASURED}".',
             '',
             f'Rendered {now.isoformat(timespec="seconds")} on {os.cpu_count()} cores, '
             f'Python {platform.python_version()}, {platform.system()} '
             f'{platform.machine()}, repository at commit `{git("rev-parse", "HEAD")[:12]}`.',
             '', "Where each run's files come from (commit, date and machine as recorded when "
             'it ran):', '']
    lines += [f'- {provenance(run, dirs[run.name])}' for row in rows for run in row.runs]
    lines += ['', '| What | Command | Result |', '|---|---|---|']
    for row in rows:
        commands = '; '.join(f'`{shown_command(r, dirs[r.name])}`' for r in row.runs)
        cost = f' ({row.cost})' if row.cost else ''
        cells = (row.what, commands + cost, result_cell(row, dirs))
        lines.append('| ' + ' | '.join(c.replace('|', '\\|').replace('\n', ' ') for c in cells)
                     + ' |')
    return '\n'.join(lines) + '\n'


def _pairs(items: Sequence[str], option: str) -> dict[str, str]:
    pairs = dict(item.partition('=')[::2] for item in items)
    if bad := [i for i in items if '=' not in i or i.partition('=')[0] not in RUNS]:
        raise ValueError(f'{option} {bad[0]!r}: give RUN=VALUE, RUN one of {",".join(RUNS)}')
    return pairs


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog='measure', description=__doc__.split('\n\n')[0])
    sub = p.add_subparsers(dest='verb', required=True)
    r = sub.add_parser('run', help="run the rows' commands")
    r.add_argument('--out', required=True, type=pathlib.Path, help='results directory')
    r.add_argument('--rows', default='', help='comma-separated row keys (default: every row)')
    r.add_argument('--force', action='store_true', help='run even where outputs exist')
    r.add_argument('--extra', action='append', default=[], metavar='RUN=ARGS',
                   help="arguments appended to one run's command, e.g. 'mesh=--seeds 2'")
    w = sub.add_parser('render', help='write the page from a results directory')
    w.add_argument('out', type=pathlib.Path, help='results directory')
    w.add_argument('--write', type=pathlib.Path, help='file to write (default: stdout)')
    w.add_argument('--from', dest='sources', action='append', default=[], metavar='RUN=DIR',
                   help="read one run's files from DIR instead")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """``measure``: run the rows' commands or render the page."""
    args = parse_args(argv)
    try:
        if args.verb == 'run':
            extra = {k: shlex.split(v) for k, v in _pairs(args.extra, '--extra').items()}
            return run_rows(select(args.rows), args.out, args.force, extra)
        sources = {k: pathlib.Path(v) for k, v in _pairs(args.sources, '--from').items()}
        if not args.out.is_dir():
            raise ValueError(f'results directory {args.out} does not exist; run: measure run '
                             f'--out {args.out}')
        page = render(args.out, sources)
    except ValueError as exc:
        print(f'measure: {exc}', file=sys.stderr)
        return 2
    if args.write:
        args.write.write_text(page, encoding='utf-8')
        print(f'measure: wrote {args.write}')
    else:
        sys.stdout.write(page)
    return 0


if __name__ == '__main__':
    sys.exit(main())
