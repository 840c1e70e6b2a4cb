"""The DSDV wire format (swarm_agent.wire) and how the router treats bad frames.

Every frame body fits the 83 bytes the authentication trailer (17 bytes) leaves of one
100-byte XBee payload. Decoders either return what was encoded
or raise ``WireError``; ``DsdvRouter.on_packet`` counts malformed, unknown-kind and
TTL-0 frames in ``stats`` and drops them, never raising into the agent loop.
"""

from __future__ import annotations

import struct

from hypothesis import example, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from swarm_agent import wire
from swarm_agent.dsdv import DsdvRouter
from swarm_agent.packet import AUTH_TRAILER, BROADCAST, Kind, MAX_BODY, MAX_PAYLOAD, Packet
from swarm_agent.wire import Advert, INFINITE_HOPS, WireError

FUZZ = settings(max_examples=200, deadline=None)


def test_frame_size_constants_fit_one_xbee_frame():
    # 83-byte body: u32 + u8 header, 7-byte entries: 11 entries are 82 bytes, 12 would be 89
    assert MAX_BODY + AUTH_TRAILER == MAX_PAYLOAD == 100
    assert wire.ADV_PER_FRAME == 11
    assert 5 + 11 * 7 <= MAX_BODY < 5 + 12 * 7
    assert wire.MAX_WHOLE == MAX_BODY - 4 - 1
    assert wire.MAX_CHUNK == MAX_BODY - 4 - 5


@given(st.integers(0, 2 ** 32 - 1), st.binary(max_size=MAX_BODY - 4))
def test_heartbeat_round_trip(seq, info):
    data = wire.encode_heartbeat(seq, info)
    assert len(data) <= MAX_BODY
    assert wire.decode_heartbeat(data) == (seq, info)


def test_heartbeat_info_too_long_rejected():
    with pytest.raises(WireError, match='exceeds one frame'):
        wire.encode_heartbeat(0, bytes(MAX_BODY - 3))


adverts = st.lists(st.builds(Advert, st.integers(0, 0xFFFF), st.integers(0, INFINITE_HOPS),
                             st.integers(0, 2 ** 32 - 1)), max_size=40)


@given(st.integers(0, 2 ** 32 - 1), adverts)
def test_adverts_round_trip_over_several_frames(seq, advs):
    frames = wire.encode_adverts(seq, advs)
    assert len(frames) == max(1, -(-len(advs) // wire.ADV_PER_FRAME))
    decoded = []
    for frame in frames:
        assert len(frame) <= MAX_BODY
        s, part = wire.decode_adverts(frame)
        assert s == seq
        decoded.extend(map(tuple, part.tolist()))
    assert decoded == advs


def test_advert_hops_saturate_at_infinity():
    (frame,) = wire.encode_adverts(2, [Advert(7, 1000, 9)])
    assert wire.decode_adverts(frame)[1].tolist() == [[7, INFINITE_HOPS, 9]]


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFFFF), st.binary(min_size=1, max_size=96))
def test_routed_round_trip(origin, second, chunk):
    assert wire.decode_routed(wire.encode_routed(origin, second, chunk)) == (
        origin, second, chunk)


@given(st.binary(max_size=3000), st.integers(0, 0xFFFF))
def test_split_and_parse_round_trip(message, frag_id):
    chunks = wire.split_message(message, frag_id)
    assert all(len(wire.encode_routed(1, 2, c)) <= MAX_BODY for c in chunks)
    parsed = [wire.parse_chunk(c) for c in chunks]
    if len(message) <= wire.MAX_WHOLE:
        assert parsed == [(message, None)]
    else:
        assert [f for _, f in parsed] == [(frag_id, i, len(chunks)) for i in range(len(chunks))]
        assert b''.join(p for p, _ in parsed) == message


def test_message_needing_more_than_255_fragments_rejected():
    with pytest.raises(WireError, match='255 fragments'):
        wire.split_message(bytes(256 * wire.MAX_CHUNK), 1)


@pytest.mark.parametrize(('decoder', 'data', 'match'), [
    (wire.decode_heartbeat, b'\x01\x02\x03', 'truncated'),
    (wire.decode_adverts, b'\x01\x00\x00', 'truncated'),
    (wire.decode_adverts, b'\x02\x00\x00\x00\x02' + bytes(7), 'must be 19 bytes'),
    (wire.decode_adverts, b'\x02\x00\x00\x00\x00' + bytes(1), 'must be 5 bytes'),
    (wire.decode_routed, b'\x01\x00\x02\x00', 'truncated'),
    (wire.parse_chunk, b'', 'empty'),
    (wire.parse_chunk, b'\x07abc', 'unknown chunk type 7'),
    (wire.parse_chunk, b'\x01\x05\x00\x00\x03', 'truncated'),
    (wire.parse_chunk, b'\x01\x05\x00\x03\x03x', 'index 3 outside count 3'),
    (wire.parse_chunk, b'\x01\x05\x00\x00\x00x', 'outside count 0'),
])
def test_malformed_bytes_raise_wire_error(decoder, data, match):
    with pytest.raises(WireError, match=match):
        decoder(data)


def test_wire_error_is_a_value_error():
    assert issubclass(WireError, ValueError)


# ------------------------------------------------------------------ router handling
def _router() -> DsdvRouter:
    return DsdvRouter(1)


@pytest.mark.parametrize(('kind', 'payload', 'counter'), [
    (Kind.HEARTBEAT, b'\x00\x00', 'rejected_malformed'),
    (Kind.DSDV_FULL, b'\x02\x00\x00\x00\x05', 'rejected_malformed'),
    (Kind.DSDV_INCREMENTAL, b'', 'rejected_malformed'),
    (Kind.DATA, b'\x02\x00\x01\x00', 'rejected_malformed'),            # no chunk
    (Kind.DATA, b'\x02\x00\x01\x00\x09hello', 'rejected_malformed'),   # bad chunk type
    (Kind.FLOOD, b'\x02\x00', 'rejected_malformed'),
    (Kind.FRAGMENT, b'\x00' * 8, 'rejected_unknown_kind'),            # no handler
    (9, b'\x00' * 8, 'rejected_unknown_kind'),
    (255, b'', 'rejected_unknown_kind'),
])
def test_router_counts_and_drops_bad_frames(kind, payload, counter):
    router = _router()
    out = router.on_packet(1.0, Packet(2, BROADCAST if kind != Kind.DATA else 1, kind, 1, 1,
                                       payload))
    assert out.packets == [] and out.delivered == []
    assert router.stats == {counter: 1}
    assert router.table == {} and router.neighbours() == set()


@pytest.mark.parametrize('kind', [Kind.HEARTBEAT, Kind.DATA, Kind.FLOOD])
def test_router_drops_ttl_zero(kind):
    """RadioPacket.msg: a packet with ttl 0 is dropped (it has used up its hops)."""
    router = _router()
    payload = (wire.encode_heartbeat(2, b'') if kind == Kind.HEARTBEAT
               else wire.encode_routed(2, 1, wire.split_message(b'hi', 1)[0]))
    dest = 1 if kind == Kind.DATA else BROADCAST
    assert router.on_packet(1.0, Packet(2, dest, kind, 1, 0, payload)).delivered == []
    assert router.stats == {'dropped_ttl': 1}
    # the same frame with ttl 1 is accepted
    assert router.on_packet(1.0, Packet(2, dest, kind, 1, 1, payload)).delivered


def test_router_ignores_own_frames_and_frames_for_others():
    router = _router()
    hb = wire.encode_heartbeat(2, b'')
    assert not router.on_packet(0.0, Packet(1, BROADCAST, Kind.HEARTBEAT, 1, 1, hb)).delivered
    assert not router.on_packet(0.0, Packet(2, 3, Kind.HEARTBEAT, 1, 1, hb)).delivered
    assert router.stats == {'not_for_me': 1} and router.table == {}


@FUZZ
@given(st.integers(0, 0xFFFF), st.sampled_from([1, BROADCAST, 5]), st.integers(0, 255),
       st.integers(0, 255), st.binary(max_size=MAX_PAYLOAD))
@example(2, BROADCAST, int(Kind.DSDV_FULL), 1, b'\xff\xff\xff\xff\x01\x01\x00\xff\xff\xff\xff\xff')
@example(2, 1, int(Kind.DATA), 1, b'\x02\x00\x01\x00\x01\x00\x00\x05\x02x')
def test_router_never_raises_on_arbitrary_frames(source, dest, kind, ttl, payload):
    """Corrupt frames only ever end up counted; the router keeps working afterwards."""
    router = _router()
    router.on_packet(0.0, Packet(source, dest, kind, 0, ttl, payload))
    router.tick(0.0)
    router.tick(10.0)
    assert all(isinstance(v, int) and v >= 0 for v in router.stats.values())
    # still answers a good heartbeat
    out = router.on_packet(11.0, Packet(3, BROADCAST, Kind.HEARTBEAT, 1, 1,
                                        wire.encode_heartbeat(4, b'info')))
    assert out.delivered[-1].payload == b'info' and router.next_hop(3) == 3


@given(st.integers(0, 2 ** 32 - 1), adverts)
def test_adverts_from_columns_are_the_documented_layout(seq, advs):
    """A route table's columns encode to the module's layout, entry by entry as struct
    packs it: ``u32 sender_sequence, u8 count`` + count x ``(u16, u8, u32)``."""
    columns = [np.array(c, dtype=np.int64) for c in zip(*advs)] if advs else \
        [np.zeros(0, np.int64)] * 3
    frames = wire.encode_advert_columns(seq, *columns)
    expected = [struct.pack('<IB', seq, len(advs[k:k + wire.ADV_PER_FRAME])) + b''.join(
        struct.pack('<HBI', *a) for a in advs[k:k + wire.ADV_PER_FRAME])
        for k in range(0, max(len(advs), 1), wire.ADV_PER_FRAME)]
    assert frames == expected == wire.encode_adverts(seq, advs)


def test_adverts_outside_the_wire_ranges_are_refused():
    with pytest.raises(WireError, match='16-bit'):
        wire.encode_adverts(0, [Advert(0x10000, 1, 2)])
    with pytest.raises(WireError, match='16-bit'):
        wire.encode_adverts(0, [Advert(3, -1, 2)])
