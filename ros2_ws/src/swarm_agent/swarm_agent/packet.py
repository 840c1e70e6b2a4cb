"""The radio packet as the brain sees it: a pure twin of swarm_msgs/RadioPacket."""

from __future__ import annotations

from dataclasses import dataclass
import enum

BROADCAST = 0xFFFF
MAX_PAYLOAD = 100  # bytes: one XBee frame


class Kind(enum.IntEnum):
    """Packet kinds; the numbers equal the KIND_* constants of swarm_msgs/RadioPacket."""

    HEARTBEAT = 0
    DSDV_FULL = 1
    DSDV_INCREMENTAL = 2
    DATA = 3
    FLOOD = 4
    FRAGMENT = 5


@dataclass(frozen=True)
class Packet:
    """One frame on the radio medium (link-level source and destination)."""

    source: int
    destination: int
    kind: int
    sequence: int
    ttl: int
    payload: bytes

    def __post_init__(self) -> None:
        if not isinstance(self.payload, bytes):
            object.__setattr__(self, 'payload', bytes(self.payload))
