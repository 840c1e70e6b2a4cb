#!/usr/bin/env python3
"""Rejoin through ROS: SIGKILL agent processes of one launcher run, one after another, and
time until each is back in every other agent's route table (docs/restarts.md).

  scripts/env.sh python benchmarks/ros_rejoin.py --agents 10 --kills 10 --out /tmp/rejoin

One per-process run of scripts/launch_swarm.py (real-time factor 1). For each kill: the
number the others hold for the agent, SIGKILL of its process, then the wall time until
every other agent holds a finite route to it whose number is at least 2 * BOOT_RATE (one
second of boot clock) newer: the respawned process's (launch_plan.RESPAWN_DELAY_S, then
its start, are in the figure). Agents are killed in turn, once each at most 3 times.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

from swarm_eval.bench.soak import writer_of

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--agents', type=int, default=10)
    parser.add_argument('--kills', type=int, default=10)
    parser.add_argument('--half-size', type=float, default=10.0)
    parser.add_argument('--domain', type=int, default=57)
    parser.add_argument('--timeout', type=float, default=40.0, help='wall s per rejoin')
    parser.add_argument('--out', required=True)
    args = parser.parse_args(argv)
    if args.agents < 4 or not 0 < args.kills <= 3 * args.agents:
        parser.error('--agents >= 4 and 0 < --kills <= 3 * agents')
    os.environ.update(ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile

    from swarm_agent.dsdv import BOOT_RATE, SEQUENCE_MASK
    from swarm_common import qos
    from swarm_msgs.msg import RouteTable
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    launcher = subprocess.Popen(
        [sys.executable, str(ROOT / 'scripts' / 'launch_swarm.py'), '--agents',
         str(args.agents), '--shape', str(ROOT / 'tests' / 'data' / 'square_8m.json'),
         '--half-size', str(args.half_size), '--duration', '3600', '--min-duration', '3600',
         '--rtf', '1', '--domain', str(args.domain), '--no-record', '--out', str(out)],
        stdout=subprocess.DEVNULL, stderr=open(out / 'stderr.txt', 'w'),  # noqa: SIM115
        start_new_session=True)
    tables: dict[int, dict[int, tuple[int, int]]] = {}
    stamps: dict[int, float] = {}   # owner -> sim time of its latest table
    lock = threading.Lock()

    def on_routes(msg) -> None:
        with lock:
            tables[int(msg.owner)] = {int(r.destination): (int(r.hop_count),
                                                            int(r.sequence_number))
                                      for r in msg.routes}
            stamps[int(msg.owner)] = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec

    def sim_now() -> float:
        return max(stamps.values())
    rclpy.init()
    node = rclpy.create_node('ros_rejoin')
    for a in range(args.agents):
        node.create_subscription(RouteTable, f'agent_{a}/routes', on_routes,
                                 QoSProfile(**qos.STATE))
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()

    def routes_to(agent: int) -> dict[int, tuple[int, int]]:
        with lock:
            return {o: t[agent] for o, t in tables.items() if o != agent and agent in t}

    def wait(condition, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and launcher.poll() is None:
            if condition():
                return True
            time.sleep(0.05)
        return condition()

    others = {a: set(range(args.agents)) - {a} for a in range(args.agents)}
    times: list[float] = []
    after: list[float] = []   # from the launcher's respawn line
    sim: list[float] = []     # sim time from SIGKILL (route tables' stamps)
    try:
        if not wait(lambda: all(set(routes_to(a)) == others[a] for a in range(args.agents)),
                    180.0):
            print('ros_rejoin: error: the mesh never joined up (see OUT/logs)', file=sys.stderr)
            return 1
        for k in range(args.kills):
            agent = k % args.agents
            old = max(seq for _, seq in routes_to(agent).values())
            pid = writer_of(out / 'logs' / f'agent_{agent}.log')
            if pid is None:
                print(f'ros_rejoin: error: agent_{agent} is not running', file=sys.stderr)
                return 1
            os.kill(pid, signal.SIGKILL)
            killed, killed_sim = time.monotonic(), sim_now()
            line = f'agent_{agent} exited with code -9; started again'
            if not wait(lambda line=line: line in (out / 'stderr.txt').read_text(), 20.0):
                print(f'ros_rejoin: error: agent_{agent} not respawned', file=sys.stderr)
                return 1
            respawned = time.monotonic()
            ok = wait(lambda agent=agent, old=old: set(routes_to(agent)) == others[agent]
                      and all(h < 255 and 2 * BOOT_RATE <= (s - old) & SEQUENCE_MASK < 1 << 31
                              for h, s in routes_to(agent).values()), args.timeout)
            took = time.monotonic() - killed if ok else float('inf')
            times.append(took)
            after.append(time.monotonic() - respawned if ok else float('inf'))
            sim.append(sim_now() - killed_sim if ok else float('inf'))
            print(f'kill {k + 1}: agent {agent} back in all {args.agents - 1} route tables '
                  f'{took:.1f} s after SIGKILL ({sim[-1]:.1f} s of sim time), {after[-1]:.1f} s '
                  'after its respawn', flush=True)
            time.sleep(3.0)
    finally:
        launcher.send_signal(signal.SIGINT)
        launcher.wait(timeout=60)
        executor.shutdown()
        spinner.join(timeout=5.0)
        node.destroy_node()
        rclpy.try_shutdown()
    print(f'ros_rejoin: {len(times)} kills; back in every route table, wall s: from SIGKILL '
          f'mean {sum(times) / len(times):.1f}, max {max(times):.1f}; from the respawn '
          f'mean {sum(after) / len(after):.1f}, max {max(after):.1f}; sim s from SIGKILL mean '
          f'{sum(sim) / len(sim):.1f}, max {max(sim):.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
