"""What the soak benchmark (benchmarks/soak.py) measures, as pure functions.

Per process of a running swarm (the launcher and every descendant, found through
/proc): proportional set size from ``/proc/PID/smaps_rollup`` (resident pages, each page
shared by k processes counted 1/k times: forked agents share their imported modules),
unique set size (private pages) and CPU time from ``/proc/PID/stat``; the sim clock
from the launcher's progress lines (``t=  123.4 s  rtf=...``) for the real-time factor;
after the run, whether and when the swarm settled (thesis eq. 4.1 held for the hold
window, ``swarm_sim.metrics``) after each shape change, replayed over the launcher's
record.npz; ``report`` turns them into the soak's figures. No ROS import.
"""

from __future__ import annotations

from collections.abc import Sequence
import json
import os
import pathlib
import re
import sys

import numpy as np

PROGRESS = re.compile(r't=\s*([0-9.]+) s\s+rtf=')


def descendants(root: int) -> list[int]:
    """``root`` and every process below it (children of children too), from /proc."""
    parents: dict[int, list[int]] = {}
    for entry in pathlib.Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            ppid = int((entry / 'stat').read_text().rsplit(')', 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        parents.setdefault(ppid, []).append(int(entry.name))
    found, todo = [], [root]
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo.extend(parents.get(pid, []))
    return sorted(found)


def writer_of(path: pathlib.Path) -> int | None:
    """The process holding ``path`` open (a node's log: the node itself, exec'd or
    forked), from /proc; None when no process does."""
    for fd_dir in pathlib.Path('/proc').glob('[0-9]*/fd'):
        try:
            if any(os.readlink(fd) == str(path) for fd in fd_dir.iterdir()):
                return int(fd_dir.parent.name)
        except OSError:
            continue
    return None


def label(pid: int) -> str:
    """A short name of a process: the module it runs (``-m module``), its script or its
    program, and its pid."""
    try:
        argv = pathlib.Path(f'/proc/{pid}/cmdline').read_bytes().decode(
            errors='replace').split('\0')
    except OSError:
        return f'pid{pid}'
    if '-m' in argv[:-1]:
        name = argv[argv.index('-m') + 1].rsplit('.', 1)[-1]
    elif len(argv) > 1 and argv[1].endswith('.py'):
        name = pathlib.Path(argv[1]).stem
    else:
        name = pathlib.Path(argv[0]).stem
    return f'{name}[{pid}]'


def memory(pid: int) -> tuple[int, int] | None:
    """The process's proportional set size (PSS) and unique set size (USS: its private
    pages, clean and dirty), in bytes, or None once it has gone. PSS also moves when
    other processes map or unmap the same libraries (on a shared machine: other
    people's Python and ROS processes); USS does not, so a leak shows in both."""
    try:
        text = pathlib.Path(f'/proc/{pid}/smaps_rollup').read_text()
    except OSError:
        return None
    kb = {line.split(':')[0]: int(line.split()[1]) for line in text.splitlines()
          if line.startswith(('Pss:', 'Private_Clean:', 'Private_Dirty:'))}
    if 'Pss' not in kb:
        return None
    return kb['Pss'] * 1024, (kb.get('Private_Clean', 0) + kb.get('Private_Dirty', 0)) * 1024


def cpu_seconds(pid: int) -> float | None:
    """User plus system CPU time of the process so far, or None once it has gone."""
    try:
        fields = pathlib.Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def processes(root: int) -> tuple[dict[str, int], dict[str, int], dict[int, float]]:
    """PSS and USS by ``label`` and CPU seconds by pid of ``root`` and its descendants
    (those that end while being read are left out)."""
    pss, uss, cpu = {}, {}, {}
    for pid in descendants(root):
        size, seconds = memory(pid), cpu_seconds(pid)
        if size is not None and seconds is not None:
            pss[label(pid)], uss[label(pid)] = size
            cpu[pid] = seconds
    return pss, uss, cpu


def sim_time(line: str) -> float | None:
    """The sim time of a launcher progress line, else None."""
    match = PROGRESS.search(line)
    return float(match[1]) if match else None


def growth_percent(wall: Sequence[float], pss: Sequence[float], warmup_s: float) -> float:
    """PSS growth from the first sample at or after ``warmup_s`` to the mean of the last
    three samples, in % of the former (the last three: one sample can catch a transient
    allocation). NaN when the run has no sample after the warm-up."""
    wall, pss = np.asarray(wall, dtype=float), np.asarray(pss, dtype=float)
    after = np.flatnonzero(wall >= warmup_s)
    if len(after) < 2:
        return float('nan')
    base = pss[after[0]]
    return float((pss[after[-3:]].mean() - base) / base * 100.0)


def rtf(sim: Sequence[float], wall: Sequence[float]) -> float:
    """Real-time factor over the samples whose sim clock runs: sim seconds per wall
    second from the first moving sample to the last."""
    sim, wall = np.asarray(sim, dtype=float), np.asarray(wall, dtype=float)
    moving = np.flatnonzero(sim > 0.0)
    if len(moving) < 2 or wall[moving[-1]] <= wall[moving[0]]:
        return float('nan')
    return float((sim[moving[-1]] - sim[moving[0]]) / (wall[moving[-1]] - wall[moving[0]]))


def settling_per_change(record: dict, change_times: Sequence[float], shapes: Sequence,
                        hold_s: float) -> list[dict]:
    """For each shape in force from ``change_times[k]`` (sim s) until the next change or
    the end of the record: settled (eq. 4.1 held ``hold_s`` before the segment ended)
    and the settling time since the change (``swarm_sim.metrics.settle_from_record``)."""
    from swarm_sim.metrics import settle_from_record

    times = np.asarray(record['times'], dtype=float)
    ends = list(change_times[1:]) + [float('inf')]
    out = []
    for begin, end, shape in zip(change_times, ends, shapes):
        seg = np.flatnonzero((times >= begin) & (times < end))
        entry = {'time': float(begin), 'shape': shape.name, 'settled': False,
                 'settling_time': None, 'recorded_until': None}
        if len(seg) >= 2:
            result = settle_from_record(
                times[seg], np.nan_to_num(np.asarray(record['positions'])[seg]),
                np.asarray(record['velocities'])[seg], shape,
                np.asarray(record['alive'])[seg], hold_s)
            entry.update(settled=bool(result['settled']),
                         recorded_until=float(times[seg[-1]]),
                         settling_time=None if result['settling_time'] is None else
                         float(times[seg[0]] - begin + result['settling_time']))
        out.append(entry)
    return out


def plot(path: pathlib.Path, samples: list[dict], change_walls: Sequence[float]) -> None:
    """PSS per process and in total, CPU and real-time factor against wall time, with
    the shape changes marked."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    wall = np.array([s['wall'] for s in samples]) / 60.0
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    total = np.array([sum(s['pss'].values()) for s in samples]) / 2**20
    axes[0].plot(wall, total, 'k', label='total')
    names = sorted({n for s in samples for n in s['pss']},
                   key=lambda n: -max(s['pss'].get(n, 0) for s in samples))
    for name in names[:6]:
        axes[0].plot(wall, [s['pss'].get(name, np.nan) / 2**20 for s in samples], lw=0.8,
                     label=name)
    axes[0].set_ylabel('PSS (MiB)')
    axes[0].legend(fontsize=7, loc='center right')
    axes[1].plot(wall, [s['cpu_cores'] for s in samples])
    axes[1].set_ylabel('CPU (cores)')
    axes[2].plot(wall, [s['rtf'] for s in samples])
    axes[2].set_ylabel('real-time factor')
    axes[2].set_xlabel('wall time (min)')
    for ax in axes:
        for t in change_walls:
            ax.axvline(t / 60.0, color='grey', ls=':', lw=0.8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def by_process_growth(samples: list[dict], key: str, warmup_s: float) -> dict[str, float]:
    """``growth_percent`` of each process present from the warm-up to the end."""
    wall = [s['wall'] for s in samples]
    names = [n for n in samples[-1].get(key, {})
             if all(n in s.get(key, {}) for s in samples if s['wall'] >= warmup_s)]
    return {n: growth_percent(wall, [s[key].get(n, np.nan) for s in samples], warmup_s)
            for n in names}


def report(args, out: pathlib.Path, samples: list[dict], changes: list[dict],
           code: int | None) -> int:
    """Figures of a finished soak from its samples and shape changes (each: shape, sim
    and wall time sent, ok): written to OUT/soak.json and OUT/soak.png and printed; the
    exit code (0: every change applied and settled)."""
    from swarm_common.shapes import load_shape
    from swarm_sim.report import dumps

    if len(samples) < 2:
        print(f'soak: the launcher ended (code {code}) before two samples; see '
              f'{out / "launch.log"}', file=sys.stderr)
        return 1
    applied = [c for c in changes if c['ok']]
    warmup = args.change_every if args.warmup is None else args.warmup
    wall = [s['wall'] for s in samples]
    figures: dict = {'warmup_s': warmup, 'wall_s': wall[-1], 'sim_s': samples[-1]['sim'],
                     'launcher_exit_code': code}
    for key in ('pss', 'uss'):
        if all(key in s for s in samples):
            total = [sum(s[key].values()) for s in samples]
            figures[f'{key}_growth_after_warmup_percent'] = growth_percent(wall, total, warmup)
            figures[f'{key}_after_warmup_mib'] = next(
                (p / 2**20 for w, p in zip(wall, total) if w >= warmup), None)
            figures[f'{key}_last_mib'] = total[-1] / 2**20
            figures[f'{key}_growth_by_process_percent'] = by_process_growth(
                samples, key, warmup)
    figures.update(cpu_cores_mean=float(np.mean([s['cpu_cores'] for s in samples[1:]])),
                   real_time_factor=rtf([s['sim'] for s in samples], wall))
    try:
        record = dict(np.load(out / 'run' / 'record.npz'))
        hold = json.loads((out / 'run' / 'metrics.json').read_text())['scenario'].get(
            'settle_hold', 30.0)
        settling = settling_per_change(record, [c['sim'] for c in applied],
                                       [load_shape(c['shape']) for c in applied], hold)
    except (OSError, ValueError, KeyError) as exc:
        print(f'soak: no settling figures: the run left no readable record ({exc})',
              file=sys.stderr)
        settling = []
    figures['changes'] = settling
    figures['refused_changes'] = [c for c in changes if not c['ok']]
    (out / 'soak.json').write_text(dumps({'figures': figures, 'args': vars(args),
                                          'changes': changes, 'samples': samples},
                                         indent=1))
    plot(out / 'soak.png', samples, [c['wall'] for c in applied])
    print(f'soak: {args.agents} agents composed, {wall[-1] / 60:.1f} min wall, '
          f'{figures["sim_s"]:.0f} s sim, loss {args.loss:g}')
    for key in ('pss', 'uss'):
        if f'{key}_last_mib' in figures:
            print(f'soak: {key.upper()} {figures[f"{key}_after_warmup_mib"] or 0:.0f} MiB at '
                  f'{warmup:.0f} s -> {figures[f"{key}_last_mib"]:.0f} MiB at the end: growth '
                  f'{figures[f"{key}_growth_after_warmup_percent"]:+.2f} % (by process: ' +
                  ', '.join(f'{n} {g:+.1f} %' for n, g in
                            figures[f'{key}_growth_by_process_percent'].items()) + ')')
    print(f'soak: CPU {figures["cpu_cores_mean"]:.2f} cores mean, real-time factor '
          f'{figures["real_time_factor"]:.3f}')
    for c in settling:
        print(f'soak: change at {c["time"]:6.0f} s sim to {c["shape"]}: ' +
              (f'settled after {c["settling_time"]:.1f} s' if c['settled'] else
               f'not settled (recorded until {c["recorded_until"]})'))
    for c in figures['refused_changes']:
        print(f'soak: change to {c["shape"]} at {c["wall"]:.0f} s wall refused: '
              f'{c["message"]}')
    print(f'soak: {out / "soak.json"}, {out / "soak.png"}')
    return 0 if settling and all(c['settled'] for c in settling) and \
        len(applied) == len(changes) else 1
