"""Application messages the agents exchange over the DSDV mesh.

The router (``swarm_agent.dsdv``) carries opaque bytes; this module defines what the
agents put in them, in a compact fixed binary layout so that one message fits one
100-byte XBee payload (its 83-byte body, ``wire.MAX_WHOLE`` = 78 bytes of message, before
the authentication trailer of ``swarm_agent.frame_auth``):

- ``NeighbourInfo``: carried in every DSDV heartbeat: type, beacon flag, mode and the
  sender's estimated position and velocity. Beacons' positions in it are what the
  others trilaterate against (thesis 3.1.1); neighbours' positions feed collision
  avoidance and the inter-member forces (eqs. 3.86-3.88).
- ``CostRow``: one agent's costs to the goals of its type for one consensus round
  (thesis 3.2.2.2), flooded to the whole mesh. Costs are quantised to centimetres:
  the quantised numbers are the ones every agent feeds to the Hungarian algorithm,
  so agents holding the same rows compute bit-identical matrices. A row whose costs
  are all below 655.35 m goes out with 16-bit costs, so 32 goals fit one frame (40, the
  larger types of a 100-robot thesis swarm, take two fragments instead of three); a
  longer one with 32-bit costs, flagged by the top bit of the goal count. Both decode
  to the same row.

Every decoder raises ``MeshMessageError`` (a ValueError) on malformed bytes. Decoding is
done once per transmission (``wire.last_result``): the receivers of one frame get the same
frozen message object.
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math
import struct

import numpy as np

from swarm_agent.wire import last_result

MSG_NEIGHBOUR_INFO = 1
MSG_COST_ROW = 2

COST_QUANTUM_M = 0.01          # cost resolution in metres
COST_UNREACHABLE = 0xFFFFFFFF  # wire value of an infinite cost

_INFO = struct.Struct('<BBBBfffff')         # kind, type, flags, mode, x, y, vx, vy, std
_ROW_HEADER = struct.Struct('<BHBIIH')      # kind, agent, type, goal_version, round, count
_NARROW_UNREACHABLE = 0xFFFF   # 16-bit wire value of an infinite cost
_WIDE = 0x8000                 # goal-count flag: 32-bit costs

FLAG_BEACON = 0x01
FLAG_SETTLED = 0x02
FLAG_ANCHOR = 0x04             # a secondary anchor (localization.py, "Secondary anchors")


class MeshMessageError(ValueError):
    """Bytes that are not a valid mesh application message."""


@dataclass(frozen=True)
class NeighbourInfo:
    """What a heartbeat tells about its sender."""

    agent_type: int
    is_beacon: bool
    mode: int
    position: tuple[float, float]
    velocity: tuple[float, float]
    settled: bool = False
    position_std: float = 0.0  # m, standard deviation of the position estimate
    anchor: bool = False       # parked, confident, localized from beacons alone

    def encode(self) -> bytes:
        """Pack into 24 bytes."""
        flags = ((FLAG_BEACON if self.is_beacon else 0) | (FLAG_SETTLED if self.settled else 0)
                 | (FLAG_ANCHOR if self.anchor else 0))
        return _INFO.pack(MSG_NEIGHBOUR_INFO, self.agent_type, flags, self.mode,
                          *self.position, *self.velocity, self.position_std)

    @classmethod
    def decode(cls, data: bytes) -> NeighbourInfo:
        """Unpack; raise MeshMessageError on anything malformed."""
        return _decode_info(data if data.__class__ is bytes else bytes(data))


@last_result
def _decode_info(data: bytes) -> NeighbourInfo:
    """NeighbourInfo.decode, once per transmission: every neighbour decodes the same
    heartbeat and gets the same frozen object."""
    if len(data) != _INFO.size:
        raise MeshMessageError(f'neighbour info must be {_INFO.size} bytes, got {len(data)}')
    kind, agent_type, flags, mode, x, y, vx, vy, std = _INFO.unpack(data)
    if kind != MSG_NEIGHBOUR_INFO:
        raise MeshMessageError(f'not a neighbour info message (kind {kind})')
    if not all(math.isfinite(v) for v in (x, y, vx, vy, std)) or std < 0:
        raise MeshMessageError('neighbour info carries a non-finite position, velocity '
                               'or standard deviation')
    return NeighbourInfo(agent_type, bool(flags & FLAG_BEACON), mode, (x, y), (vx, vy),
                         bool(flags & FLAG_SETTLED), std, bool(flags & FLAG_ANCHOR))


@dataclass(frozen=True)
class CostRow:
    """Costs of one agent to the goals of its type, for one consensus round.

    ``costs`` follow the goal-id order of that type's goals in the goal list of
    ``goal_version``; ``quantised`` holds the integer centimetres actually sent.
    """

    agent_id: int
    agent_type: int
    goal_version: int
    round: int
    quantised: tuple[int, ...]

    @classmethod
    def from_costs(cls, agent_id: int, agent_type: int, goal_version: int, round_: int,
                   costs: np.ndarray) -> CostRow:
        """Quantise float costs (metres, inf = unreachable)."""
        costs = np.asarray(costs, dtype=float)
        q = np.where(np.isfinite(costs),
                     np.minimum(np.round(costs / COST_QUANTUM_M), COST_UNREACHABLE - 1),
                     COST_UNREACHABLE).astype(np.int64)
        return cls(agent_id, agent_type, goal_version, round_, tuple(q.tolist()))

    @property
    def costs(self) -> np.ndarray:
        """Costs in metres (inf for unreachable goals)."""
        q = np.asarray(self.quantised, dtype=np.int64)
        return np.where(q == COST_UNREACHABLE, np.inf, q * COST_QUANTUM_M)

    def encode(self) -> bytes:
        """Pack into 14 + 2 * len(costs) bytes, or 14 + 4 * len(costs) when a finite cost
        is 655.35 m or more (the router fragments if needed)."""
        return self._encoded

    @functools.cached_property
    def _encoded(self) -> bytes:
        """The encoding, computed once per row object: the assignment digest
        (``AgentBrain._assign``) encodes every row held at every round."""
        count = len(self.quantised)
        if count >= _WIDE:
            raise MeshMessageError(f'a cost row holds at most {_WIDE - 1} goals, got {count}')
        wide = any(q >= _NARROW_UNREACHABLE and q != COST_UNREACHABLE for q in self.quantised)
        if wide:
            body = struct.pack(f'<{count}I', *self.quantised)
        else:
            body = struct.pack(f'<{count}H', *(_NARROW_UNREACHABLE if q == COST_UNREACHABLE
                                               else q for q in self.quantised))
        return _ROW_HEADER.pack(MSG_COST_ROW, self.agent_id, self.agent_type,
                                self.goal_version, self.round,
                                count | (_WIDE if wide else 0)) + body

    @functools.cached_property
    def keyed(self) -> bytes:
        """The agent id (2 bytes) and the encoding: what the assignment digest is computed
        over, row after row (``AgentBrain._assign``)."""
        return self.agent_id.to_bytes(2, 'little') + self._encoded

    @classmethod
    def decode(cls, data: bytes) -> CostRow:
        """Unpack; raise MeshMessageError on anything malformed."""
        return _decode_row(data if data.__class__ is bytes else bytes(data))


@last_result
def _decode_row(data: bytes) -> CostRow:
    """CostRow.decode, once per transmission (the receivers of one flood frame)."""
    if len(data) < _ROW_HEADER.size:
        raise MeshMessageError(f'cost row truncated to {len(data)} bytes')
    kind, agent, agent_type, goal_version, round_, count = _ROW_HEADER.unpack_from(data)
    if kind != MSG_COST_ROW:
        raise MeshMessageError(f'not a cost row (kind {kind})')
    wide = bool(count & _WIDE)
    count &= _WIDE - 1
    expected = _ROW_HEADER.size + (4 if wide else 2) * count
    if len(data) != expected:
        raise MeshMessageError(
            f'cost row of {count} goals must be {expected} bytes, got {len(data)}')
    if wide:
        quantised = struct.unpack_from(f'<{count}I', data, _ROW_HEADER.size)
    else:
        quantised = tuple(COST_UNREACHABLE if q == _NARROW_UNREACHABLE else q
                          for q in struct.unpack_from(f'<{count}H', data, _ROW_HEADER.size))
    return CostRow(agent, agent_type, goal_version, round_, tuple(quantised))


def message_kind(data: bytes) -> int:
    """First byte of an application payload, or raise on empty bytes."""
    if not data:
        raise MeshMessageError('empty mesh message')
    return data[0]
