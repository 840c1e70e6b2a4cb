"""The mission computer as a node of the mesh: liveness learned over the radio.

The thesis's mission computer talks to the swarm through the same XBee mesh as the
robots. Here it listens: a DSDV router (``swarm_agent.dsdv``) of its own, at the
radio address ``MISSION_RADIO_ID``, takes the route adverts it hears from the agents
around it. Through their full dumps it learns a route to every agent its mesh component
holds; when an agent falls silent, its neighbours time it out and advertise the broken
route (Fig. 3.9), which reaches the mission the same way. ``alive`` names the agents
the mission holds a finite route to now: those it hears of, hop by hop. It sends
nothing, so the agents' routing and consensus do not change. Like every node of the mesh
it opens each frame first (``swarm_agent.frame_auth``) and drops, counted in
``auth.stats``, what fails.
"""

from __future__ import annotations

from collections.abc import Iterable

from swarm_agent.dsdv import DsdvConfig, DsdvRouter, INFINITE_HOPS
from swarm_agent.dsdv_receive import hear
from swarm_agent.frame_auth import FrameAuth, open_all
from swarm_agent.packet import Kind, Packet
from swarm_agent.reception import Receivers

MISSION_RADIO_ID = 0xFFFE   # below BROADCAST (0xFFFF); no agent may use it
ADVERT_KINDS = (int(Kind.DSDV_FULL), int(Kind.DSDV_INCREMENTAL))  # what the mission hears


class MeshListener:
    """The mission's radio; see the module docstring."""

    def __init__(self, agent_ids: Iterable[int], node_id: int = MISSION_RADIO_ID,
                 config: DsdvConfig | None = None, auth: FrameAuth | None = None) -> None:
        """``auth`` opens the frames heard; None: unauthenticated (comparisons)."""
        self.auth = auth
        self.agents = {int(a) for a in agent_ids}
        if node_id in self.agents:
            raise ValueError(f"agent id {node_id} is the mission's radio address; give the "
                             f'agents ids below {node_id}')
        self.router = DsdvRouter(node_id, config)
        self.frames = 0
        self._alone = Receivers((self,))   # what opening and routing ask of it, once

    @property
    def id(self) -> int:
        return self.router.id

    def on_packet(self, t: float, packet: Packet) -> None:
        """A frame the mission's radio heard; only route adverts concern it."""
        if packet.kind in ADVERT_KINDS:
            if self.auth is not None:
                packet = open_all(self._alone.auths, packet, self._alone.opening)[0]
                if packet is None:
                    return
            self.frames += 1
            hear(t, packet, self._alone.routers, self._alone.takers())

    def alive(self) -> list[int]:
        """Agents the mission holds a finite route to, in id order."""
        table = self.router.table
        return sorted(a for a in self.agents
                      if (r := table.get(a)) is not None and r.hop_count < INFINITE_HOPS)
