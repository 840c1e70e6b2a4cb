"""The XBee mesh between the agents of the hardware-in-the-loop world (thesis Fig. 5.1).

The brains' frames travel through the simulator's radio medium
(``swarm_sim.medium.RadioMedium``, configured by the same ``MediumConfig``): a frame is
heard only by robots within ``range_m`` and in line of sight of its sender, each
receiver drops it with probability ``loss``, and it arrives after the sender's airtime
plus ``latency_s``. The robots' positions are the emulated boards' poses. Pure: no
rclpy; ``hil_world_node`` feeds it frames and poses and publishes what is due.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
import math

import numpy as np
from shapely.geometry import Polygon

from swarm_agent.packet import Packet
from swarm_sim.medium import MediumConfig, RadioMedium


class HilMesh:
    """The medium between the agents ``agent_ids``; see the module docstring."""

    def __init__(self, agent_ids: Iterable[int], config: MediumConfig, seed: int,
                 obstacles: Sequence[Polygon] = ()) -> None:
        if not (math.isfinite(config.latency_s) and config.latency_s >= 0.0):
            raise ValueError(f'radio latency must be a finite number >= 0 s, got '
                             f'{config.latency_s}')
        self.ids = [int(a) for a in agent_ids]
        self.medium = RadioMedium(config, np.random.default_rng(seed), obstacles)
        self._known = set(self.ids)

    def move(self, positions: Mapping[int, Sequence[float]]) -> None:
        """The robots' positions (m, map frame) by agent id; recomputes the links."""
        ids = [a for a in self.ids if a in positions]
        self.medium.update_positions(ids, [positions[a][:2] for a in ids])

    def send(self, t: float, packet: Packet) -> bool:
        """Put a frame on the air at time ``t`` (s); False for a sender not in the fleet."""
        if packet.source not in self._known:
            return False
        self.medium.transmit(t, packet)
        return True

    def due(self, t: float) -> list[tuple[Packet, list[int]]]:
        """Frames that have arrived by ``t``, in arrival order, each with its receivers."""
        return self.medium.deliver_grouped(t)
