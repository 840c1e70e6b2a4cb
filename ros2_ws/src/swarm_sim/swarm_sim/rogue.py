"""Rogue transmitters on the swarm's radio: attackers without the swarm key.

A rogue knows the wire format (``swarm_agent.wire``, ``mesh_messages``, the
authentication trailer of ``swarm_agent.frame_auth``) and hears every frame on the air
(``overhear``), but not the key. So it can only send frames whose tags it cannot compute,
or genuine frames verbatim (replays). Four kinds (``ROGUE_KINDS``; ``make_rogue``):

- ``adverts`` (``ForgedAdverts``): the black-hole attack. It impersonates one address
  and, every ``period_s``, sends full dumps advertising every agent one hop away with a
  sequence number far ahead of the real ones. Unauthenticated, every robot routes
  through the impersonated address, counts every agent as its neighbour (so its flood
  relaying prunes itself) and the mission's radio counts removed agents as alive.
- ``costs`` (``ForgedCostRows``): steers the assignment (thesis 3.2.2.2). For every
  consensus round whose genuine cost rows it overhears (type, goal version, round and
  goal count are in plain text), it floods rows of phantom agents (addresses no robot
  has) that cost 0 m to every goal of that type, as many phantoms as goals. The
  Hungarian algorithm (Alg. 6) minimises the summed cost, so the phantoms take every
  goal and every real agent is left unassigned: it parks where it stands. Goals
  themselves reach the agents from the mission over ROS (a transient-local topic), not
  over the radio: the cost rows are the radio's share of the assignment.
- ``replay`` (``ReplayFrames``): records every frame it overhears and sends it again,
  verbatim (trailer included), ``delay_s`` later. Unauthenticated, stale heartbeats
  (old positions of beacons and neighbours) and removed agents' frames come back.
- ``flood`` (``FloodFrames``): ``factor`` (10) frames for every frame on the air, i.e.
  ten times the swarm's own frame rate: half verbatim replays, half with the counter
  advanced (the tag no longer matches).

With a trailer (``trailer=True``: the receivers authenticate) forged frames carry key
id 1, a counter and a tag of zeros; the receivers drop them as ``auth_bad_tag`` and
replays as ``auth_replay`` / ``auth_too_old``. Without, they are plain frames.

A replay reaches a receiver that never heard the original frame (lost, or out of the
source's range) as a fresh one: the replay window cannot tell a late copy from a
delayed frame. The rogue's power here is the worst case otherwise: it hears every
delivery and reaches every living robot (and, headless, the mission's radio) directly,
outside the medium's range, loss and airtime, so it draws nothing from the medium's
random stream. Jamming the channel itself is a physical-layer attack no frame check
stops (docs/security.md).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
import struct

from swarm_agent.frame_auth import TAG_BYTES, TRAILER_BYTES
from swarm_agent.mesh_messages import CostRow, MSG_COST_ROW
from swarm_agent.packet import BROADCAST, Kind, Packet
from swarm_agent.wire import Advert, encode_adverts, encode_routed, parse_chunk, split_message

ROGUE_KINDS = ('adverts', 'costs', 'replay', 'flood')   # sim_node's ``rogue`` = 1..4
# Phantom agents' addresses, below BROADCAST and far above the fleets' ids (0..N-1 as the
# launcher numbers them); a phantom sharing a real id would overwrite that agent's row.
PHANTOM_BASE = 0xFE00
_COUNTER = struct.Struct('<Q')


def check_rogue(value: float) -> float:
    """sim_node's ``rogue`` setting: 0 (none) or 1..4 (``ROGUE_KINDS``), or ValueError."""
    value = float(value)
    if value not in range(len(ROGUE_KINDS) + 1):
        raise ValueError(f'rogue must be 0 (none) or 1..{len(ROGUE_KINDS)} '
                         f'({", ".join(f"{k + 1} {n}" for k, n in enumerate(ROGUE_KINDS))}), '
                         f'got {value:g}')
    return value


def _seal(body: bytes, counter: int) -> bytes:
    """A trailer the receivers expect, with a tag the rogue cannot compute (zeros)."""
    return body + struct.pack('<BQ', 1, counter) + bytes(TAG_BYTES)


@dataclass
class Rogue:
    """What every rogue offers: it overhears frames and has frames due at ``t``."""

    trailer: bool = True     # the receivers authenticate: frames end with a trailer
    start_s: float = 0.0     # silent before this time (s)
    frames_sent: int = 0

    def overhear(self, t: float, packet: Packet) -> None:
        """A frame on the air at ``t`` (s)."""

    def frames(self, t: float) -> list[Packet]:
        """The frames due at ``t`` (s); counted in ``frames_sent``."""
        out = self._due(t) if t >= self.start_s else []
        self.frames_sent += len(out)
        return out

    def _due(self, t: float) -> list[Packet]:
        return []


@dataclass
class ForgedAdverts(Rogue):
    """Forged DSDV adverts, metric 1 (module docstring). ``source``: the address
    impersonated."""

    agent_ids: Sequence[int] = ()
    source: int = 0
    period_s: float = 1.0
    sequence_lead: int = 1 << 20   # ahead of any real sequence number of a short run
    _next: float | None = None

    def _due(self, t: float) -> list[Packet]:
        if self._next is not None and t < self._next:
            return []
        self._next = t + self.period_s
        sequence = self.sequence_lead + 2 * int(t)      # even: a live destination
        adverts = [Advert(a, 1 if a != self.source else 0, sequence)
                   for a in self.agent_ids]
        return [Packet(self.source, BROADCAST, int(Kind.DSDV_FULL), k, 1,
                       _seal(body, self.frames_sent + k) if self.trailer else body)
                for k, body in enumerate(encode_adverts(sequence, adverts))]


@dataclass
class ForgedCostRows(Rogue):
    """Phantom agents' cost rows of 0 m to every goal (module docstring)."""

    _rounds: set = field(default_factory=set)    # (type, goal version, round) forged
    _pending: list = field(default_factory=list)
    _flood_id: int = 0

    def overhear(self, t: float, packet: Packet) -> None:
        if packet.kind != Kind.FLOOD:
            return
        body = packet.payload[:-TRAILER_BYTES] if self.trailer else packet.payload
        try:
            message, fragment = parse_chunk(body[4:])
            if fragment is not None or message[:1] != bytes([MSG_COST_ROW]):
                return
            row = CostRow.decode(message)
        except ValueError:
            return
        key = (row.agent_type, row.goal_version, row.round)
        if key in self._rounds:
            return
        self._rounds.add(key)
        for k in range(len(row.quantised)):
            phantom = PHANTOM_BASE + k
            forged = CostRow(phantom, row.agent_type, row.goal_version, row.round,
                             (0,) * len(row.quantised))
            self._flood_id = (self._flood_id + 1) & 0xFFFF
            for chunk in split_message(forged.encode(), self._flood_id):
                self._pending.append((phantom, packet.ttl,
                                      encode_routed(phantom, self._flood_id, chunk)))

    def _due(self, t: float) -> list[Packet]:
        out = [Packet(phantom, BROADCAST, int(Kind.FLOOD), self.frames_sent + k, ttl,
                      _seal(body, self.frames_sent + k) if self.trailer else body)
               for k, (phantom, ttl, body) in enumerate(self._pending)]
        self._pending.clear()
        return out


@dataclass
class ReplayFrames(Rogue):
    """Every overheard frame again, verbatim, ``delay_s`` later (module docstring)."""

    delay_s: float = 2.0
    _captured: deque = field(default_factory=deque)   # (time heard, frame)

    def overhear(self, t: float, packet: Packet) -> None:
        self._captured.append((t, packet))

    def _due(self, t: float) -> list[Packet]:
        out = []
        while self._captured and self._captured[0][0] <= t - self.delay_s:
            out.append(self._captured.popleft()[1])
        return out


@dataclass
class FloodFrames(Rogue):
    """``factor`` frames for every frame on the air (module docstring)."""

    factor: int = 10
    _heard: list = field(default_factory=list)

    def overhear(self, t: float, packet: Packet) -> None:
        self._heard.append(packet)

    def _due(self, t: float) -> list[Packet]:
        out = []
        for packet in self._heard:
            for k in range(self.factor):
                if k % 2 == 0 or not self.trailer or len(packet.payload) < TRAILER_BYTES:
                    out.append(packet)     # verbatim
                    continue
                payload = bytearray(packet.payload)
                at = len(payload) - TAG_BYTES - _COUNTER.size
                counter = _COUNTER.unpack_from(payload, at)[0]
                _COUNTER.pack_into(payload, at, (counter + k) & ((1 << 64) - 1))
                out.append(Packet(packet.source, packet.destination, packet.kind,
                                  packet.sequence, packet.ttl, bytes(payload)))
        self._heard.clear()
        return out


def make_rogue(kind: str, agent_ids: Sequence[int], trailer: bool = True,
               start_s: float = 0.0) -> Rogue:
    """A rogue of ``kind`` (``ROGUE_KINDS``) against the swarm ``agent_ids``; forged
    adverts impersonate the first agent. ValueError naming the kinds for another."""
    if kind == 'adverts':
        return ForgedAdverts(trailer, start_s, agent_ids=list(agent_ids),
                             source=int(agent_ids[0]))
    if kind == 'costs':
        return ForgedCostRows(trailer, start_s)
    if kind == 'replay':
        return ReplayFrames(trailer, start_s)
    if kind == 'flood':
        return FloodFrames(trailer, start_s)
    raise ValueError(f'unknown rogue {kind!r}; use one of {", ".join(ROGUE_KINDS)}')
