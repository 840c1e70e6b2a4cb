#!/usr/bin/env python3
"""What a frame costs a brain that is alone in its process (a per-process agent node).

  scripts/env.sh python benchmarks/bench_one_receiver.py [--duration 40] [--repeat 3]

Records the transmissions of the 50-agent thesis trial (``run_trial(ScenarioSpec(),
0)``, its first ``--duration`` simulated seconds) with their receivers, then hands them
again to fresh brains that each hold their own route, neighbour and replay stores, one
receiver a call (``AgentBrain.on_packet``, what ``agent_node`` calls). Prints the CPU
microseconds per delivery of each repeat. Run it in two trees one after the other (or at
once, one core each) to compare them.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from swarm_agent import frame_auth
from swarm_agent.agent_factory import make_brain
from swarm_eval.scenario import run_trial, ScenarioSpec
from swarm_sim import headless


def record(duration: float) -> list[tuple[float, object, list[int]]]:
    """(time, frame, receiver ids) of every transmission of the trial's first seconds."""
    frames: list[tuple[float, object, list[int]]] = []
    receive = headless.receive

    def recording(t, packet, heard):     # heard: a reception.Receivers
        frames.append((t, packet, [brain.config.agent_id for brain in heard.brains]))
        receive(t, packet, heard)

    headless.receive = recording
    try:
        run_trial(dataclasses.replace(ScenarioSpec(), duration=duration), 0)
    finally:
        headless.receive = receive
    return frames


def replay(frames: list[tuple[float, object, list[int]]]) -> float:
    """CPU microseconds per delivery, each receiver a brain with stores of its own."""
    ids = sorted({i for _, _, receivers in frames for i in receivers})
    brains = {i: make_brain(agent_id=i, agent_type=1, is_beacon=False, method='bubble',
                            initial_position=(0.0, 0.0), seed=i, boot_time_s=0.0)
              for i in ids}
    deliveries = 0
    # The frames were sealed in this process, which knows their tags good: a node hears
    # frames sealed elsewhere and checks each tag.
    frame_auth._OPENED.clear()
    start = time.process_time()
    for t, packet, receivers in frames:
        for i in receivers:
            brains[i].on_packet(t, packet)
        deliveries += len(receivers)
    return (time.process_time() - start) / deliveries * 1e6


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=40.0,
                        help='simulated seconds of the trial recorded (default 40)')
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args()
    if args.duration <= 0 or args.repeat < 1:
        parser.error('--duration must be positive and --repeat at least 1')
    frames = record(args.duration)
    deliveries = sum(len(receivers) for _, _, receivers in frames)
    print(f'{len(frames)} transmissions, {deliveries} deliveries in {args.duration:g} s')
    costs = [replay(frames) for _ in range(args.repeat)]
    print('us per delivery, one receiver a call:', ' '.join(f'{c:.1f}' for c in costs))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
