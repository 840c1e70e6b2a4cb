#!/usr/bin/env python3
"""Executor cost of many composed agent-like nodes (DESIGN.md: measure EventsExecutor).

Each node has a timer at --rate Hz (wall time) that publishes a WrenchStamped, and one
subscription that receives every node's messages on a shared topic subset. Prints one
JSON line per executor: achieved callback rate, CPU cores used per 1000 callbacks/s.

  scripts/env.sh python benchmarks/bench_executor.py --nodes 50 --rate 50 --seconds 5
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

from geometry_msgs.msg import WrenchStamped
import rclpy
from rclpy.executors import SingleThreadedExecutor


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run(kind: str, nodes: int, rate: float, seconds: float) -> dict:
    context = rclpy.Context()
    rclpy.init(context=context)
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    counts = {'timer': 0, 'sub': 0}
    made = []
    for i in range(nodes):
        node = rclpy.create_node(f'bench_{i}', namespace=f'/agent_{i}', context=context)
        pub = node.create_publisher(WrenchStamped, 'cmd_force', 5)

        def tick(pub=pub):
            counts['timer'] += 1
            pub.publish(WrenchStamped())

        node.create_timer(1.0 / rate, tick)
        node.create_subscription(WrenchStamped, f'/agent_{(i + 1) % nodes}/cmd_force',
                                 lambda m: counts.__setitem__('sub', counts['sub'] + 1), 5)
        executor.add_node(node)
        made.append(node)
    t0, c0 = time.monotonic(), cpu()
    end = t0 + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    wall, used = time.monotonic() - t0, cpu() - c0
    executor.shutdown()
    for node in made:
        node.destroy_node()
    rclpy.try_shutdown(context=context)
    callbacks = counts['timer'] + counts['sub']
    return {'executor': kind, 'nodes': nodes, 'rate_hz': rate,
            'timer_rate_achieved': counts['timer'] / wall / nodes,
            'callbacks_per_s': callbacks / wall, 'cpu_cores': used / wall,
            'cores_per_1000_cb_s': used / wall / max(callbacks / wall / 1000, 1e-9),
            'cpu_count': os.cpu_count()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--nodes', type=int, default=50)
    parser.add_argument('--rate', type=float, default=50.0)
    parser.add_argument('--seconds', type=float, default=5.0)
    parser.add_argument('--executors', nargs='+', default=['single', 'events'])
    args = parser.parse_args()
    for kind in args.executors:
        print(json.dumps(run(kind, args.nodes, args.rate, args.seconds)), flush=True)


if __name__ == '__main__':
    main()
