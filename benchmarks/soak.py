#!/usr/bin/env python3
"""Soak: the composed swarm through ROS for an hour, a shape change every 10 minutes.

  scripts/env.sh python benchmarks/soak.py --out results/soak      # 1 h, 50 agents
  scripts/env.sh python benchmarks/soak.py --agents 12 --duration 180 \\
      --change-every 60 --out /tmp/soak_short                     # a 3-minute try

Runs scripts/launch_swarm.py (composed agents, real-time factor target 1, radio loss
--loss from t = 0, the shapes of --shapes in turn every --change-every sim seconds)
until --duration wall seconds have passed (then SIGINT: the launcher stops its children
and writes its results into OUT/run). Every --sample wall seconds it records the PSS and
CPU time of every process of the swarm and the sim clock (benchmarks/soak_probe.py), one
JSON line per sample in OUT/samples.jsonl, written as it goes. At the end: OUT/soak.json
(samples and figures), OUT/soak.png, and the figures printed: PSS growth after the
warm-up (default: the first change period), mean CPU, real-time factor and, per shape
change, whether the swarm settled (eq. 4.1 held for the hold window) and when.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import soak_probe as probe

ROOT = pathlib.Path(__file__).resolve().parent.parent


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--agents', type=int, default=50)
    p.add_argument('--beacons', type=int, default=8)
    p.add_argument('--duration', type=float, default=3600.0, help='wall seconds')
    p.add_argument('--change-every', type=float, default=600.0, help='sim seconds')
    p.add_argument('--shapes', default='thesis_shape_1,thesis_shape_2',
                   help='shapes formed in turn, comma-separated')
    p.add_argument('--loss', type=float, default=0.05, help='radio packet loss')
    p.add_argument('--sample', type=float, default=10.0, help='wall seconds between samples')
    p.add_argument('--warmup', type=float, default=None,
                   help='wall seconds before the PSS baseline (default: --change-every)')
    p.add_argument('--no-record', action='store_true', help='no MCAP bag of the topics')
    p.add_argument('--out', required=True)
    args = p.parse_args(argv)
    if not (args.duration > 0 and args.change_every > 0 and args.sample > 0
            and 0.0 <= args.loss < 1.0):
        p.error('--duration, --change-every and --sample must be > 0, --loss in [0, 1)')
    return args


def launch_command(args: argparse.Namespace, sequence: pathlib.Path, run: pathlib.Path):
    first = args.shapes.split(',')[0]
    cmd = [sys.executable, str(ROOT / 'scripts' / 'launch_swarm.py'), '--composed',
           '--agents', str(args.agents), '--beacons', str(args.beacons), '--rtf', '1',
           '--shape', first, '--sequence', str(sequence), '--duration', str(args.duration),
           '--min-duration', str(args.duration), '--set-sim', f'0:loss={args.loss:g}',
           '--out', str(run)]
    return cmd + (['--no-record'] if args.no_record else [])


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    shapes = [s.strip() for s in args.shapes.split(',') if s.strip()]
    changes = list(np.arange(0.0, args.duration, args.change_every))
    names = [shapes[k % len(shapes)] for k in range(len(changes))]
    sequence = out / 'sequence.yaml'
    sequence.write_text('sequence:\n' + ''.join(f'  - {{time: {t:g}, shape: {n}}}\n'
                                                 for t, n in zip(changes, names)))
    cmd = launch_command(args, sequence, out / 'run')
    (out / 'command.txt').write_text(' '.join(cmd) + '\n')
    log = open(out / 'launch.log', 'w', encoding='utf-8')  # noqa: SIM115
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, cwd=ROOT)
    wall0 = time.monotonic()
    clock: list[tuple[float, float]] = [(0.0, 0.0)]    # (wall, sim) of progress lines

    def read() -> None:
        for line in proc.stdout:
            log.write(line)
            log.flush()
            t = probe.sim_time(line)
            if t is not None:
                clock.append((time.monotonic() - wall0, t))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    samples: list[dict] = []
    cpu_before: dict[int, float] = {}
    last = (0.0, 0.0)
    with open(out / 'samples.jsonl', 'w', encoding='utf-8') as jsonl:
        while proc.poll() is None:
            time.sleep(min(args.sample, 1.0))
            wall = time.monotonic() - wall0
            if wall >= args.duration and proc.poll() is None:
                proc.send_signal(signal.SIGINT)     # the launcher writes its results
                break
            if samples and wall - samples[-1]['wall'] < args.sample:
                continue
            pss, cpu, used = {}, {}, 0.0
            for pid in probe.descendants(proc.pid):
                size, seconds = probe.pss_bytes(pid), probe.cpu_seconds(pid)
                if size is None or seconds is None:
                    continue
                pss[probe.label(pid)] = size
                cpu[pid] = seconds
                used += seconds - cpu_before.get(pid, 0.0)
            span = wall - (samples[-1]['wall'] if samples else 0.0)
            now = clock[-1]
            rate = (now[1] - last[1]) / (now[0] - last[0]) if now[0] > last[0] else 0.0
            samples.append({'wall': wall, 'sim': now[1], 'pss': pss,
                            'cpu_cores': used / span, 'rtf': rate})
            cpu_before, last = cpu, now
            jsonl.write(json.dumps(samples[-1]) + '\n')
            jsonl.flush()
    code = proc.wait()
    reader.join(timeout=10.0)
    return report(args, out, samples, clock, changes, names, code)


def report(args, out: pathlib.Path, samples: list[dict], clock, changes, names,
           code: int) -> int:
    from swarm_common.shapes import load_shape
    from swarm_sim.report import dumps

    if len(samples) < 2:
        print(f'soak: the launcher ended (code {code}) before two samples; see '
              f'{out / "launch.log"}', file=sys.stderr)
        return 1
    walls, sims = zip(*clock)
    change_walls = [float(np.interp(t, sims, walls)) for t in changes if t <= sims[-1]]
    warmup = args.change_every if args.warmup is None else args.warmup
    total = [sum(s['pss'].values()) for s in samples]
    wall = [s['wall'] for s in samples]
    figures = {'pss_growth_after_warmup_percent': probe.growth_percent(wall, total, warmup),
               'warmup_s': warmup, 'pss_first_after_warmup_mib': next(
                   (p / 2**20 for w, p in zip(wall, total) if w >= warmup), None),
               'pss_last_mib': total[-1] / 2**20,
               'cpu_cores_mean': float(np.mean([s['cpu_cores'] for s in samples[1:]])),
               'real_time_factor': probe.rtf(sims, walls), 'wall_s': wall[-1],
               'sim_s': sims[-1], 'launcher_exit_code': code}
    try:
        record = dict(np.load(out / 'run' / 'record.npz'))
        hold = json.loads((out / 'run' / 'metrics.json').read_text())['scenario'].get(
            'settle_hold', 30.0)
        settling = probe.settling_per_change(record, changes,
                                             [load_shape(n) for n in names], hold)
    except (OSError, ValueError, KeyError) as exc:
        print(f'soak: no settling figures: the run left no readable record ({exc})',
              file=sys.stderr)
        settling = []
    figures['changes'] = settling
    (out / 'soak.json').write_text(dumps({'figures': figures, 'args': vars(args),
                                          'samples': samples}, indent=1))
    probe.plot(out / 'soak.png', samples, change_walls)
    print(f'soak: {args.agents} agents composed, {wall[-1] / 60:.1f} min wall, '
          f'{sims[-1]:.0f} s sim, loss {args.loss:g}')
    print(f'soak: PSS {figures["pss_first_after_warmup_mib"] or 0:.0f} MiB at '
          f'{warmup:.0f} s -> {total[-1] / 2**20:.0f} MiB at the end: growth '
          f'{figures["pss_growth_after_warmup_percent"]:+.2f} %')
    print(f'soak: CPU {figures["cpu_cores_mean"]:.2f} cores mean, real-time factor '
          f'{figures["real_time_factor"]:.3f}')
    for c in settling:
        print(f'soak: change at {c["time"]:6.0f} s to {c["shape"]}: ' +
              (f'settled after {c["settling_time"]:.1f} s' if c['settled'] else
               f'not settled (recorded until {c["recorded_until"]})'))
    print(f'soak: {out / "soak.json"}, {out / "soak.png"}')
    return 0 if settling and all(c['settled'] for c in settling) else 1


if __name__ == '__main__':
    sys.exit(main())
