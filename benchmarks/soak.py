#!/usr/bin/env python3
"""Soak: the composed swarm through ROS for an hour, a shape change every 10 minutes.

  scripts/env.sh python benchmarks/soak.py --out results/soak      # 1 h, 50 agents
  ... --agents 12 --duration 180 --change-every 60 --out /tmp/soak  # a 3-minute try

Runs scripts/launch_swarm.py (composed, real-time factor target 1, radio loss --loss)
for --duration wall seconds (then SIGINT: the launcher writes OUT/run); once the sim
clock runs, every --change-every wall seconds the next shape of --shapes through the
mission node's swarm/set_shape (soak_shapes.py). Every --sample s: PSS, USS, CPU of
the swarm's processes and the sim clock (swarm_eval.bench.soak) into OUT/samples.jsonl,
changes into OUT/changes.jsonl, as they happen. At the end OUT/soak.json, OUT/soak.png
and the figures: memory growth after --warmup, CPU, RTF, settling (eq. 4.1) per change.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

from swarm_eval.bench import soak as probe

ROOT = pathlib.Path(__file__).resolve().parent.parent


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--agents', type=int, default=50)
    p.add_argument('--beacons', type=int, default=8)
    p.add_argument('--duration', type=float, default=3600.0, help='wall seconds')
    p.add_argument('--change-every', type=float, default=600.0, help='wall seconds')
    p.add_argument('--shapes', default='thesis_shape_1,thesis_shape_2',
                   help='shapes formed in turn, comma-separated')
    p.add_argument('--loss', type=float, default=0.05, help='radio packet loss')
    p.add_argument('--sample', type=float, default=10.0, help='wall seconds between samples')
    p.add_argument('--warmup', type=float, default=None,
                   help='wall seconds before the PSS baseline (default: --change-every)')
    p.add_argument('--no-record', action='store_true', help='no MCAP bag of the topics')
    p.add_argument('--domain', type=int, default=None,
                   help='ROS domain (default: a free one, swarm_common.domains)')
    p.add_argument('--report-only', action='store_true',
                   help="the figures again from OUT's samples.jsonl and changes.jsonl")
    p.add_argument('--out', required=True)
    args = p.parse_args(argv)
    if not (args.duration > 0 and args.change_every > 0 and args.sample > 0
            and 0.0 <= args.loss < 1.0):
        p.error('--duration, --change-every and --sample must be > 0, --loss in [0, 1)')
    return args


def launch_command(args: argparse.Namespace, first: str, run: pathlib.Path) -> list[str]:
    """The launcher's command: a run longer in sim time than the soak in wall time."""
    sim = str(10.0 * args.duration)
    cmd = [sys.executable, str(ROOT / 'scripts' / 'launch_swarm.py'), '--composed',
           '--agents', str(args.agents), '--beacons', str(args.beacons), '--rtf', '1',
           '--shape', first, '--duration', sim, '--min-duration', sim, '--set-sim',
           f'0:loss={args.loss:g}', '--domain', str(args.domain), '--out', str(run)]
    return cmd + (['--no-record'] if args.no_record else [])


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    if args.report_only:
        samples, changes = ([json.loads(line) for line in open(out / name, encoding='utf-8')]
                            for name in ('samples.jsonl', 'changes.jsonl'))
        return probe.report(args, out, samples, changes, None)
    out.mkdir(parents=True, exist_ok=True)
    if args.domain is None:
        from swarm_common.domains import claim_domain
        args.domain, domain_lock = claim_domain(start=os.getpid())   # held to the end
    shapes = [s.strip() for s in args.shapes.split(',') if s.strip()]
    cmd = launch_command(args, shapes[0], out / 'run')
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

    changes = [{'shape': shapes[0], 'sim': 0.0, 'wall': 0.0, 'ok': True}]
    changes_file = open(out / 'changes.jsonl', 'w', encoding='utf-8')  # noqa: SIM115
    changes_file.write(json.dumps(changes[0]) + '\n')

    def change_shapes() -> None:
        from soak_shapes import ShapeChanger

        changer = ShapeChanger(args.domain)
        while clock[-1][1] <= 0.0 and proc.poll() is None:
            time.sleep(0.5)
        start = time.monotonic() - wall0
        # No change in the last half period: it could not settle before the end.
        count = int((args.duration - 0.5 * args.change_every - start) // args.change_every)
        for k in range(1, count + 1):
            time.sleep(max(0.0, start + k * args.change_every - (time.monotonic() - wall0)))
            if proc.poll() is not None:
                break
            wall = time.monotonic() - wall0
            changes.append({**changer.change(shapes[k % len(shapes)]), 'wall': wall})
            changes_file.write(json.dumps(changes[-1]) + '\n')
            changes_file.flush()
            print(f'soak: {wall:.0f} s wall: {changes[-1]}', flush=True)
        changer.close()

    for target in (read, change_shapes):
        threading.Thread(target=target, daemon=True).start()
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
            pss, uss, cpu = probe.processes(proc.pid)
            used = sum(c - cpu_before.get(pid, 0.0) for pid, c in cpu.items())
            span = wall - (samples[-1]['wall'] if samples else 0.0)
            now = clock[-1]
            rate = (now[1] - last[1]) / (now[0] - last[0]) if now[0] > last[0] else 0.0
            samples.append({'wall': wall, 'sim': now[1], 'pss': pss, 'uss': uss,
                            'cpu_cores': used / span, 'rtf': rate})
            cpu_before, last = cpu, now
            jsonl.write(json.dumps(samples[-1]) + '\n')
            jsonl.flush()
    code = proc.wait()
    time.sleep(1.0)     # the reader's last lines
    return probe.report(args, out, samples, changes, code)


if __name__ == '__main__':
    sys.exit(main())
