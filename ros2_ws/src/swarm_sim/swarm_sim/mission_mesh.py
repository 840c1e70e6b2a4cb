"""The mission computer's radio beside the simulated medium.

``MediumWithMission`` wraps the robots' ``RadioMedium`` and adds one more radio at a
fixed position: the mission's ``MeshListener`` (``swarm_agent.mission_radio``). It
hears the route adverts the agents send around it with the same range, line of sight,
loss, airtime and latency as any robot would (a second ``RadioMedium`` with the same
config object, holding the mission and the robots within range of it, with random
draws of its own). The robots' medium is left as it was: its links, deliveries, TOA
ranges and random draws do not change, and the agents never see the mission's radio.
Faults (range, loss, walls, obstacles, radios off) apply to both.

In the headless evaluator the listener is the mission's ``MeshListener`` itself; sim_node
gives a ``RelayedListener``, whose frames it publishes on ``mission/radio/rx`` for the
mission node's own ``MeshListener``: one medium, one listener, in both modes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from shapely.geometry import Polygon

from swarm_agent.mission_radio import ADVERT_KINDS, MeshListener, MISSION_RADIO_ID
from swarm_agent.packet import Packet
from swarm_sim.medium import RadioMedium, SweepingWall

MISSION_RADIO_STREAM = 0x4D52   # seeds the mission radio's losses apart from the rest


class RelayedListener:
    """The mission's radio in sim_node: keeps what it hears for sim_node to publish."""

    def __init__(self, node_id: int = MISSION_RADIO_ID) -> None:
        self.id = node_id
        self.heard: list[tuple[float, Packet]] = []

    def on_packet(self, t: float, packet: Packet) -> None:
        self.heard.append((t, packet))

    def take(self) -> list[tuple[float, Packet]]:
        """The frames heard since the last call."""
        heard, self.heard = self.heard, []
        return heard


class MediumWithMission:
    """The robots' medium plus the mission's radio; see the module docstring.
    Attributes not defined here are the robots' medium's."""

    def __init__(self, medium: RadioMedium, listener: MeshListener | RelayedListener,
                 position: Sequence[float], rng: np.random.Generator,
                 obstacles: Sequence[Polygon] = ()) -> None:
        self.medium = medium
        self.listener = listener
        self.position = np.asarray(position, dtype=float).reshape(2)
        if not np.all(np.isfinite(self.position)):
            raise ValueError(f'the mission radio position {list(position)} is not finite')
        self.reach = RadioMedium(medium.config, rng, obstacles)
        self._heard_from: set[int] = set()

    def __getattr__(self, name: str):
        if name == 'medium' or name.startswith('__'):   # not set yet (copy, unpickling)
            raise AttributeError(name)
        return getattr(self.medium, name)

    def update_positions(self, ids: Sequence[int], positions) -> None:
        """The robots' true positions; the mission's radio stays where it is."""
        self.medium.update_positions(ids, positions)
        xy = np.asarray(positions, dtype=float).reshape(-1, 2)
        near = np.flatnonzero(np.hypot(*(xy - self.position).T) <= self.medium.config.range_m)
        me = self.listener.id
        self.reach.update_positions([me, *(int(ids[k]) for k in near)],
                                    np.vstack([self.position, xy[near]]))
        self._heard_from = set(self.reach.neighbours(me))

    def transmit(self, t: float, packet: Packet) -> None:
        self.medium.transmit(t, packet)
        if packet.kind in ADVERT_KINDS and packet.source in self._heard_from:
            self.reach.transmit(t, packet)

    def deliver_grouped(self, t: float) -> list[tuple[Packet, list[int]]]:
        """The robots' deliveries; what reached the mission goes to its listener."""
        me = self.listener.id
        for packet, receivers in self.reach.deliver_grouped(t):
            if me in receivers:
                self.listener.on_packet(t, packet)
        return self.medium.deliver_grouped(t)

    def deliver(self, t: float) -> list[tuple[int, Packet]]:
        return [(r, packet) for packet, receivers in self.deliver_grouped(t) for r in receivers]

    # Faults act on both media (range and loss live in their shared config).
    def set_obstacles(self, obstacles: Sequence[Polygon]) -> None:
        self.medium.set_obstacles(obstacles)
        self.reach.set_obstacles(obstacles)

    def start_wall(self, wall: SweepingWall | None) -> None:
        self.medium.start_wall(wall)
        self.reach.start_wall(wall)

    def move_wall(self, t: float) -> float | None:
        self.reach.move_wall(t)
        return self.medium.move_wall(t)

    def disable_radio(self, agent_id: int) -> None:
        self.medium.disable_radio(agent_id)
        self.reach.disable_radio(agent_id)

    def enable_radio(self, agent_id: int) -> None:
        self.medium.enable_radio(agent_id)
        self.reach.enable_radio(agent_id)

    def remove(self, agent_id: int) -> None:
        self.medium.remove(agent_id)
        self.reach.remove(agent_id)
