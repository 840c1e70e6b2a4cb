#!/usr/bin/env python3
"""What one call of each compiled kernel costs, compiled and as its Python source.

  scripts/env.sh python benchmarks/bench_kernels.py [--receivers 22] [--repeat 2000]

Both ways in the same run (``swarm_common.jit.use_python``), on the work of the 50-agent
thesis trial: a collision filter with 1-7 neighbours, a 50-advert route dump, a
heartbeat and a sealed frame heard by ``--receivers`` brains of one process (22 on
average in that trial), a Kalman prediction and a zero-velocity update, one step of 50
point masses and the parked test of 50 robots' proximity scans. Prints microseconds per
call and the ratio.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from swarm_agent import neighbour_table, route_table
from swarm_agent.dynamics import PointMassSwarm
from swarm_agent.frame_auth import FrameAuth, Keyring, open_all, ReplayStore
from swarm_agent.kalman import KalmanFilter
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.setpoint import avoid_collisions, SetpointParams, stays_parked_each
from swarm_common import jit
from swarm_common.robot_types import load_robot_types
from swarm_sim.sensors import ProximityModel


def _per_call_us(work, calls: int) -> float:
    work()                                   # compiles (or loads) before timing
    start = time.perf_counter()
    for _ in range(calls):
        work()
    return (time.perf_counter() - start) / calls * 1e6


def cases(receivers: int) -> dict[str, tuple[str, object]]:
    rng = np.random.default_rng(0)
    params = SetpointParams()
    scenes = []
    for _ in range(64):
        k = int(rng.integers(1, 8))
        scenes.append((rng.uniform(-0.5, 0.5, 2), rng.uniform(-1.2, 1.2, (k, 2)),
                       np.full(k, 0.3), rng.uniform(-0.3, 0.3, 2)))
    cycle = iter(range(1 << 62))

    def avoid() -> None:
        v, offsets, radii, own = scenes[next(cycle) % len(scenes)]
        avoid_collisions(v, offsets, radii, 0.3, params, own_velocity=own, lag_s=0.6)

    store = route_table.RouteStore()
    tables = [route_table.RouteTable(store, 100 + k) for k in range(receivers)]
    adverts = np.array([[d, 1 + d % 4, 1000 + 2 * (d % 3)] for d in range(50)],
                       dtype=np.int64)

    rows = np.array([table.row for table in tables], dtype=np.int64)

    def dump() -> None:
        route_table.merge(store, rows, 12, 7, adverts)

    def heartbeat() -> None:
        route_table.heard(store, rows, 7, 1000, 0)

    beats = iter(range(1 << 62))

    def neighbour() -> None:
        neighbour_table.heard(store.neighbours, rows, 7, 0.5 * next(beats), True, 0.5, 0.95)

    kf = KalmanFilter((1.0, 2.0), consider_time_s=30.0)
    kf.cross = rng.normal(0.0, 0.01, (6, 6))   # three anchors held as consider parameters
    accel = np.array([0.01, -0.02])
    zero, r_velocity = np.zeros(2), np.eye(2) * 0.01 ** 2

    def predict() -> None:
        kf.predict(0.02, accel)

    def stand_still() -> None:
        kf.update_velocity(zero, r_velocity)

    key = Keyring(((1, bytes(range(32))),), seal_id=1)
    sender = FrameAuth(key, lambda: 1.8e9)
    replay = ReplayStore()
    auths = [FrameAuth(key, lambda: 1.8e9, store=replay) for _ in range(receivers)]
    frame = Packet(4, BROADCAST, int(Kind.HEARTBEAT), 1, 1, b'\x00' * 30)

    def opened() -> None:
        open_all(auths, sender.seal(frame))

    types = load_robot_types()
    swarm = PointMassSwarm([types[1 + k % 3] for k in range(50)], rng.uniform(0, 50, (50, 2)))
    forces = rng.normal(0.0, 5.0, (50, 2))

    def point_masses() -> None:
        swarm.step(0.02, forces)

    positions = rng.uniform(0.0, 30.0, (50, 2))
    scan = ProximityModel(rng).measure(positions, np.full(50, 0.3))
    starts, ends = scan.rows_of(np.arange(50))
    every = [params] * 50

    def parked() -> None:
        stays_parked_each(scan.offsets, scan.radii, starts.tolist(), ends.tolist(),
                          [0.3] * 50, every)

    return {'collision filter (setpoint._avoid)': ('1-7 neighbours', avoid),
            'selection rules (route_table._merge)': (f'50 adverts x {receivers}', dump),
            'link addition (route_table._heard)': (f'heartbeat x {receivers}', heartbeat),
            'neighbours heard (neighbour_table._heard_from)': (f'heartbeat x {receivers}',
                                                                neighbour),
            'Kalman prediction (kalman._propagate)': ('6 states, 3 anchors', predict),
            'zero-velocity update (kalman._update)': ('6 states, 3 anchors', stand_still),
            'replay windows (frame_auth._accept)': (f'frame x {receivers}, tag once',
                                                     opened),
            'point masses (dynamics._step)': ('50 robots, one step', point_masses),
            'parked scans (setpoint._stays_parked)': ("50 robots' scans", parked)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--receivers', type=int, default=22)
    parser.add_argument('--repeat', type=int, default=2000)
    args = parser.parse_args()
    if not jit.compiled():
        print('bench_kernels: numba is not in use here (SWARM_JIT=0 or not installed)')
        return 1
    work = cases(args.receivers)
    print(f'{"kernel":46s} {"work":26s} {"source us":>10s} {"compiled us":>12s} {"ratio":>6s}')
    for name, (what, call) in work.items():
        jit.use_python(True)
        source = _per_call_us(call, max(args.repeat // 20, 10))
        jit.use_python(False)
        compiled = _per_call_us(call, args.repeat)
        print(f'{name:46s} {what:26s} {source:10.1f} {compiled:12.2f} {source / compiled:6.1f}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
