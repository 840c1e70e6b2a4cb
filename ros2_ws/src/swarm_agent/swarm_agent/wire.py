"""Compact binary wire format of the DSDV mesh (thesis 3.1.2); every frame body <= 83 bytes.

Little-endian layouts (the packet header itself travels in swarm_msgs/RadioPacket or
the XBee frame around it). Each body below is at most ``MAX_BODY`` (83) bytes: the
authentication trailer (``swarm_agent.frame_auth``, 17 bytes) fills a frame to the
100-byte XBee payload:

- HEARTBEAT: ``u32 own_sequence`` + application info blob (the sender's NeighbourInfo).
- DSDV_FULL / DSDV_INCREMENTAL: ``u32 sender_sequence, u8 count`` + count x
  ``(u16 destination, u8 hops, u32 destination_sequence)``; 11 entries per frame.
- DATA (routed unicast): ``u16 origin, u16 final_destination`` + app chunk.
- FLOOD (mesh-wide broadcast): ``u16 origin, u16 flood_id`` + app chunk.
- app chunk: ``u8 0`` + whole message, or ``u8 1, u16 fragment_id, u8 index, u8 count`` +
  piece, for messages longer than one frame (reassembled at the destination).

Decoders raise ``WireError`` (a ValueError) naming what is wrong; the router catches
and counts them, so malformed bytes never reach the agent loop.

Decoded once per transmission: one transmission reaches all its receivers as the same
frame object, one receiver after another (the headless evaluator, a composed process's
sensor batch; ``frame_auth`` opens it once), so the decoders of frame bodies keep their
last result by the identity of their argument (``last_result``): the receivers after the
first get the very same decoded value, which is immutable (tuples, frozen dataclasses,
bytes) or an array they only read (a dump's adverts).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import functools
import struct
from typing import NamedTuple, TypeVar

import numpy as np

from swarm_agent.packet import MAX_BODY

INFINITE_HOPS = 255
_HB = struct.Struct('<I')
_ADV_HEAD = struct.Struct('<IB')
_ADV_ENTRY = struct.Struct('<HBI')
# The same entry as a numpy record (packed, as struct's '<'), for a route table's columns.
_ADV_ARRAY = np.dtype([('destination', '<u2'), ('hops', 'u1'), ('sequence', '<u4')])
_ROUTED = struct.Struct('<HH')
_FRAG = struct.Struct('<BHBB')
ADV_PER_FRAME = (MAX_BODY - _ADV_HEAD.size) // _ADV_ENTRY.size
CHUNK_WHOLE = 0
CHUNK_FRAGMENT = 1
MAX_CHUNK = MAX_BODY - _ROUTED.size - _FRAG.size  # app bytes per fragment
MAX_WHOLE = MAX_BODY - _ROUTED.size - 1


_T = TypeVar('_T')


class WireError(ValueError):
    """Bytes that are not a valid frame of the given kind."""


def last_result(decode: Callable[[bytes], _T]) -> Callable[[bytes], _T]:
    """``decode`` with its last result kept by the identity of its argument.

    Only a ``bytes`` argument is kept (immutable: the same object always holds the same
    bytes), and it is referenced, so its identity cannot be reused by another object; a
    call that raises keeps nothing. The (argument, result) pair is replaced in one
    assignment, so a reader on another thread never sees a mismatched pair.
    """
    last: tuple[object, object] = (None, None)

    @functools.wraps(decode)
    def cached(data: bytes) -> _T:
        nonlocal last
        kept = last
        if data is kept[0]:
            return kept[1]
        result = decode(data)
        if data.__class__ is bytes:
            last = (data, result)
        return result

    return cached


class Advert(NamedTuple):
    """One advertised route: destination, hop count (255 = broken), its sequence number.
    A tuple: decoded straight from the frame's entries, and unpacked by every receiver."""

    destination: int
    hops: int
    sequence: int


def encode_heartbeat(sequence: int, info: bytes) -> bytes:
    if _HB.size + len(info) > MAX_BODY:
        raise WireError(f'heartbeat info of {len(info)} bytes exceeds one frame')
    return _HB.pack(sequence & 0xFFFFFFFF) + info


@last_result
def decode_heartbeat(data: bytes) -> tuple[int, bytes]:
    """(sender sequence, application info) of a heartbeat."""
    if len(data) < _HB.size:
        raise WireError(f'heartbeat truncated to {len(data)} bytes')
    return _HB.unpack_from(data)[0], bytes(data[_HB.size:])


def encode_adverts(sender_sequence: int, adverts: Sequence[Advert]) -> list[bytes]:
    """Route adverts split into frames of at most ADV_PER_FRAME entries."""
    columns = np.array(adverts, dtype=np.int64).reshape(-1, 3)
    return encode_advert_columns(sender_sequence, columns[:, 0], columns[:, 1],
                                 columns[:, 2])


def encode_advert_columns(sender_sequence: int, destinations: np.ndarray, hops: np.ndarray,
                          sequences: np.ndarray) -> list[bytes]:
    """``encode_adverts`` of the adverts given as three integer arrays (a route table's
    columns: no tuple per advert). Hops saturate at INFINITE_HOPS and sequence numbers
    wrap to 32 bits; a destination outside 16 bits or negative hops raise WireError."""
    n = len(destinations)
    if n and (destinations.min() < 0 or destinations.max() > 0xFFFF or hops.min() < 0):
        raise WireError('advert destinations must be 16-bit addresses and hops not '
                        'negative')
    entries = np.empty(n, _ADV_ARRAY)
    entries['destination'] = destinations
    entries['hops'] = np.minimum(hops, INFINITE_HOPS)
    entries['sequence'] = sequences & 0xFFFFFFFF
    body, size = entries.tobytes(), _ADV_ENTRY.size
    return [_ADV_HEAD.pack(sender_sequence & 0xFFFFFFFF, min(ADV_PER_FRAME, n - k))
            + body[k * size:(k + ADV_PER_FRAME) * size]
            for k in range(0, max(n, 1), ADV_PER_FRAME)]


@last_result
def decode_adverts(data: bytes) -> tuple[int, np.ndarray]:
    """(sender sequence, adverts) of a DSDV frame, the adverts as a (k, 3) int64 array
    of destination, hops and sequence number (the columns a route table's kernel
    reads; read, never written), read from the frame's bytes as numpy records: no
    object per advert.

    Also kept by content: advert frames repeat across transmissions (an incremental
    update sent again unchanged): in the 50-agent thesis trial (seed 0) the content
    cache decodes 20,003 of the 71,236 frames the identity one misses.
    """
    return _adverts(data) if data.__class__ is bytes else _adverts.__wrapped__(data)


@functools.lru_cache(maxsize=4096)
def _adverts(data: bytes) -> tuple[int, np.ndarray]:
    if len(data) < _ADV_HEAD.size:
        raise WireError(f'advert truncated to {len(data)} bytes')
    seq, count = _ADV_HEAD.unpack_from(data)
    if len(data) != _ADV_HEAD.size + count * _ADV_ENTRY.size:
        raise WireError(f'advert of {count} entries must be '
                        f'{_ADV_HEAD.size + count * _ADV_ENTRY.size} bytes, got {len(data)}')
    entries = np.frombuffer(data, _ADV_ARRAY, count, _ADV_HEAD.size)
    rows = np.empty((count, 3), dtype=np.int64)
    rows[:, 0] = entries['destination']
    rows[:, 1] = entries['hops']
    rows[:, 2] = entries['sequence']
    # Shared by every receiver of the frame, which only reads it; left writeable so
    # that the kernels see the array type they were compiled for (jit.warm).
    return seq, rows


def encode_routed(origin: int, second: int, chunk: bytes) -> bytes:
    """DATA (second = final destination) or FLOOD (second = flood id) frame payload."""
    return _ROUTED.pack(origin, second & 0xFFFF) + chunk


@last_result
def decode_routed(data: bytes) -> tuple[int, int, bytes]:
    """(origin, second, chunk) of a DATA or FLOOD frame."""
    origin, second = decode_routed_header(data)
    return origin, second, bytes(data[_ROUTED.size:])


def decode_routed_header(data: bytes) -> tuple[int, int]:
    """(origin, second) of a routed frame without copying its chunk: most floods a
    robot hears are copies it has already seen."""
    if len(data) < _ROUTED.size + 1:
        raise WireError(f'routed frame truncated to {len(data)} bytes')
    return _ROUTED.unpack_from(data)


@last_result
def routed_key(data: bytes) -> tuple[int, int] | None:
    """(origin, second) of a routed frame, or None when it is too short to be one."""
    return _ROUTED.unpack_from(data) if len(data) > _ROUTED.size else None


ROUTED_HEADER_SIZE = _ROUTED.size


def split_message(message: bytes, fragment_id: int) -> list[bytes]:
    """App message -> chunks (one whole chunk, or fragments)."""
    if len(message) <= MAX_WHOLE:
        return [bytes([CHUNK_WHOLE]) + message]
    pieces = [message[k:k + MAX_CHUNK] for k in range(0, len(message), MAX_CHUNK)]
    if len(pieces) > 255:
        raise WireError(f'message of {len(message)} bytes needs more than 255 fragments')
    return [_FRAG.pack(CHUNK_FRAGMENT, fragment_id & 0xFFFF, i, len(pieces)) + p
            for i, p in enumerate(pieces)]


@last_result
def parse_chunk(chunk: bytes) -> tuple[bytes | None, tuple[int, int, int] | None]:
    """(whole message, None) or (piece, (fragment id, index, count))."""
    if not chunk:
        raise WireError('empty chunk')
    if chunk[0] == CHUNK_WHOLE:
        return bytes(chunk[1:]), None
    if chunk[0] == CHUNK_FRAGMENT:
        if len(chunk) <= _FRAG.size:
            raise WireError(f'fragment truncated to {len(chunk)} bytes')
        _, frag_id, index, count = _FRAG.unpack_from(chunk)
        if count == 0 or index >= count:
            raise WireError(f'fragment index {index} outside count {count}')
        return bytes(chunk[_FRAG.size:]), (frag_id, index, count)
    raise WireError(f'unknown chunk type {chunk[0]}')
