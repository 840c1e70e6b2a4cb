#!/usr/bin/env python3
"""Cost of authenticated radio frames (swarm_agent.frame_auth): bytes and microseconds.

Seals ``--frames`` frames of the mesh's typical sizes (a heartbeat, a full dump of 11
adverts, a cost row of 20 goals) and hands each, as the medium does, to ``--receivers``
receivers in a row (28: the mean of the 50-agent thesis scenario), each with its own
replay window: the first computes the HMAC, the others find the result kept. Prints the
trailer's bytes per frame, microseconds per seal and per delivery; with the frame counts
of an evaluator run (its metrics.json: medium.sent, medium.delivered) the CPU time
authentication adds to that run, to set beside its measured time.

``--evaluator SECONDS`` measures the whole cost in the headless evaluator: two
processes side by side (the same load on both), each running the 50-agent thesis
scenario (seed 0) for SECONDS of sim time, one authenticated, one not but with frames
given the trailer's airtime, so that both runs are the same frame for frame and only the
checks differ; prints the CPU seconds of each.

  scripts/env.sh python benchmarks/bench_frame_auth.py --frames 20000
  scripts/env.sh python benchmarks/bench_frame_auth.py --metrics DIR/metrics.json
  scripts/env.sh python benchmarks/bench_frame_auth.py --evaluator 150
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import time

import numpy as np

from swarm_agent import wire
from swarm_agent.frame_auth import FrameAuth, Keyring, TRAILER_BYTES
from swarm_agent.mesh_messages import CostRow, NeighbourInfo
from swarm_agent.packet import BROADCAST, Kind, Packet

KEY = Keyring(((1, bytes(range(32))),), seal_id=1)


def _bodies() -> list[tuple[int, bytes]]:
    info = NeighbourInfo(1, False, 0, (1.0, 2.0), (0.0, 0.0)).encode()
    dump = wire.encode_adverts(4, [wire.Advert(k, 2, 8) for k in range(11)])[0]
    row = wire.encode_routed(3, 9, wire.split_message(
        CostRow.from_costs(3, 1, 1, 7, np.arange(20.0)).encode(), 1)[0])
    return [(int(Kind.HEARTBEAT), wire.encode_heartbeat(6, info)),
            (int(Kind.DSDV_FULL), dump), (int(Kind.FLOOD), row)]


def bench(frames: int, receivers: int = 28) -> dict:
    bodies = _bodies()
    plain = [Packet(k % 50, BROADCAST, kind, k & 0xFFFF, 1, body)
             for k, (kind, body) in zip(range(frames), bodies * (frames // len(bodies) + 1))]
    sender = FrameAuth(KEY)
    t0 = time.perf_counter()
    sealed = [sender.seal(p) for p in plain]
    t1 = time.perf_counter()
    hearing = [FrameAuth(KEY) for _ in range(receivers)]
    for p in sealed:
        for r in hearing:
            r.open(p)
    t2 = time.perf_counter()
    assert not any(r.stats for r in hearing)
    return {'frames': frames, 'trailer_bytes': TRAILER_BYTES,
            'body_bytes': {Kind(kind).name: len(body) for kind, body in bodies},
            'seal_us': 1e6 * (t1 - t0) / frames,
            'delivery_us': 1e6 * (t2 - t1) / (frames * receivers)}


def evaluator_run(mode: str, duration: float) -> str:
    """One headless run (``auth`` or ``padded``); its CPU seconds and frame counts."""
    from swarm_eval.scenario import build_scenario, ScenarioSpec
    from swarm_sim.headless import HeadlessSwarm
    import swarm_sim.medium as medium

    if mode == 'padded':
        medium.FRAME_OVERHEAD_BYTES += TRAILER_BYTES
    swarm = HeadlessSwarm(build_scenario(ScenarioSpec(duration=duration,
                                                      auth=mode == 'auth'), 0))
    c0 = time.process_time()
    record = swarm.run()
    cpu = time.process_time() - c0
    m = record.metrics['medium']
    return (f'{mode}: {record.times[-1]:.0f} s simulated, {cpu:.1f} s CPU, {m["sent"]} '
            f'frames sent, {m["delivered"]} delivered')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--frames', type=int, default=20000)
    parser.add_argument('--receivers', type=int, default=28)
    parser.add_argument('--metrics', default='', help="an evaluator run's metrics.json")
    parser.add_argument('--evaluator', type=float, default=0.0, metavar='SECONDS',
                        help='A/B of the headless evaluator (module docstring)')
    parser.add_argument('--one', choices=('auth', 'padded'), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:
        print(evaluator_run(args.one, args.evaluator))
        return 0
    if args.evaluator > 0.0:
        runs = [subprocess.Popen([sys.executable, __file__, '--evaluator',
                                  str(args.evaluator), '--one', mode],
                                 stdout=subprocess.PIPE, text=True)
                for mode in ('auth', 'padded')]
        for run in runs:
            print(run.communicate()[0].strip())
        return 0
    r = bench(args.frames, args.receivers)
    print(f'trailer {r["trailer_bytes"]} bytes per frame (bodies {r["body_bytes"]}); '
          f'seal {r["seal_us"]:.2f} us a frame, open {r["delivery_us"]:.2f} us a delivery '
          f'({args.receivers} receivers a frame)')
    if args.metrics:
        trial = json.loads(pathlib.Path(args.metrics).read_text())['trials'][0]
        sent, delivered = trial['medium']['sent'], trial['medium']['delivered']
        cpu = 1e-6 * (sent * r['seal_us'] + delivered * r['delivery_us'])
        print(f'{sent} frames sent, {delivered} deliveries: about {cpu:.1f} s of CPU for '
              f'authentication, beside {trial["wall_seconds"]:.1f} s wall for the run '
              f'({trial["real_time_factor"]:.2f} x real time)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
