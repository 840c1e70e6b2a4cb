"""A rogue transmitter on the swarm's radio: forged DSDV adverts (the black-hole attack).

``ForgedAdverts`` impersonates one address and, every ``period_s``, sends full dumps
that advertise every agent one hop away with a sequence number far ahead of the real
ones. Without authentication each robot that hears it takes the impersonated address as
the next hop to everyone (routes black-holed), counts every agent as that address's
neighbour (so its flood relaying prunes itself: cost rows stop spreading), and the
mission's radio counts removed agents as alive. It knows the frame format: with
``trailer`` its frames end with an authentication trailer (key id 1, a counter, a tag it
cannot compute), as the receivers expect; without, they are plain adverts for receivers
that do not authenticate.

Its power is the worst case: it reaches every robot and the mission directly, outside
the medium's range and loss (``HeadlessSwarm`` hands its frames to every receiver), so
it draws nothing from the medium's random stream and an authenticated run with it is
the clean run, bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import struct

from swarm_agent.frame_auth import TAG_BYTES
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.wire import Advert, encode_adverts


@dataclass
class ForgedAdverts:
    """See the module docstring. ``source``: the address impersonated."""

    agent_ids: Sequence[int]
    source: int
    start_s: float = 0.0
    period_s: float = 1.0
    sequence_lead: int = 1 << 20   # ahead of any real sequence number of a short run
    trailer: bool = True
    _next: float | None = None
    frames_sent: int = 0

    def frames(self, t: float) -> list[Packet]:
        """The forged frames due at ``t`` (s)."""
        if t < self.start_s or (self._next is not None and t < self._next):
            return []
        self._next = t + self.period_s
        sequence = self.sequence_lead + 2 * int(t)      # even: a live destination
        adverts = [Advert(a, 1 if a != self.source else 0, sequence)
                   for a in self.agent_ids]
        out = []
        for k, frame in enumerate(encode_adverts(sequence, adverts)):
            if self.trailer:
                frame += struct.pack('<BQ', 1, self.frames_sent + k) + bytes(TAG_BYTES)
            out.append(Packet(self.source, BROADCAST, int(Kind.DSDV_FULL), k, 1, frame))
        self.frames_sent += len(out)
        return out
