"""Fuzzing of the frame authentication (swarm_agent.frame_auth) and the key file parser.

``FrameAuth.open`` takes every frame the radio hears: on any header and payload it must
return the frame without its trailer or None (counted), never raise; a frame it accepts
was sealed under the key, and is accepted once. The key file loader raises only
``FrameAuthError``.
"""

from __future__ import annotations

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import yaml

from swarm_agent.agent_factory import make_brain
from swarm_agent.frame_auth import (
    FrameAuth,
    FrameAuthError,
    Keyring,
    load_keyring,
    REJECTIONS,
    TRAILER_BYTES,
)
from swarm_agent.packet import MAX_BODY, MAX_PAYLOAD, Packet

FUZZ = settings(max_examples=150, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
KEY = Keyring(((1, bytes(range(32))), (9, bytes(32))), seal_id=1)
U16 = st.integers(0, 0xFFFF)
header = st.tuples(st.one_of(st.integers(0, 12), U16, st.integers(-5, 0x1FFFF)),
                   st.one_of(U16, st.integers(-5, 0x1FFFF)),
                   st.one_of(st.integers(0, 5), st.integers(-3, 300)),
                   st.integers(-5, 0x1FFFF),
                   st.one_of(st.integers(0, 40), st.integers(-3, 300)))


@FUZZ
@given(header, st.binary(max_size=MAX_PAYLOAD + 20))
def test_open_never_raises_and_rejects_unsealed_bytes(fields, payload):
    receiver = FrameAuth(KEY, lambda: 1.8e9)
    assert receiver.open(Packet(*fields, payload)) is None
    assert sum(receiver.stats.values()) == 1 and set(receiver.stats) <= set(REJECTIONS)


valid_header = st.tuples(U16, U16, st.integers(0, 255), U16, st.integers(0, 255))


@FUZZ
@given(st.lists(st.tuples(valid_header, st.binary(max_size=MAX_BODY),
                          st.integers(-1, MAX_PAYLOAD), st.integers(0, 255)), max_size=20),
       st.randoms(use_true_random=False))
def test_sealed_frames_open_once_and_any_flip_is_rejected(items, rnd):
    """Frames sealed by several senders, some with one bit flipped, delivered in a
    shuffled order with duplicates: each genuine frame is accepted at most once, no
    flipped one ever, and every rejection is counted."""
    senders = {}
    receiver = FrameAuth(KEY, lambda: 1.8e9)
    sent = []
    for fields, body, flip_at, bit in items:
        sender = senders.setdefault(fields[0], FrameAuth(KEY, lambda: 1.8e9))
        sealed = sender.seal(Packet(*fields, body))
        payload = bytearray(sealed.payload)
        flipped = 0 <= flip_at < len(payload)
        if flipped:
            payload[flip_at] ^= 1 << (bit % 8)
        sent.append((flipped, Packet(*fields, bytes(payload)), body))
    deliveries = sent + [rnd.choice(sent) for _ in range(len(sent) // 2)] if sent else []
    rnd.shuffle(deliveries)
    accepted = []
    for flipped, packet, body in deliveries:
        opened = receiver.open(packet)
        if opened is not None:
            assert not flipped and opened.payload == body
            accepted.append(packet)
    assert len(accepted) == len({id(p) for p in accepted})
    assert len(accepted) + sum(receiver.stats.values()) == len(deliveries)


key_doc = st.one_of(
    st.fixed_dictionaries({'seal': st.one_of(st.integers(-2, 300), st.text(max_size=3)),
                           'keys': st.dictionaries(
                               st.one_of(st.integers(-2, 300), st.text(max_size=3)),
                               st.one_of(st.binary(min_size=0, max_size=40).map(bytes.hex),
                                         st.text(max_size=10), st.integers()),
                               max_size=3)},
                          optional={'development': st.one_of(st.booleans(), st.text())}),
    st.dictionaries(st.text(max_size=5), st.integers(), max_size=2), st.text(max_size=20))


@FUZZ
@given(key_doc)
def test_key_file_loader_raises_only_its_error(tmp_path, doc):
    path = tmp_path / 'keys.yaml'
    path.write_text(doc if isinstance(doc, str) else yaml.safe_dump(doc))
    load_keyring.cache_clear()
    try:
        ring = load_keyring(str(path))
    except FrameAuthError as exc:
        assert str(path) in str(exc) and '\n' not in str(exc)
    else:
        assert ring.key(ring.seal_id) is not None


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(valid_header, st.binary(max_size=MAX_PAYLOAD)), max_size=25))
def test_authenticated_brain_drops_every_forged_frame(items):
    """Frames of a sender without the key never reach the router: no neighbour, no
    route, each counted."""
    brain = make_brain(agent_id=7, agent_type=1, initial_position=(0.0, 0.0))
    forger = FrameAuth(Keyring(((1, bytes(32)),), seal_id=1), lambda: 1.8e9)
    for k, (fields, payload) in enumerate(items):
        packet = Packet(*fields, payload)
        if len(payload) + TRAILER_BYTES <= 255 and k % 2:
            packet = forger.seal(packet)
        brain.on_packet(0.1 * k, packet)
        assert np.all(np.isfinite(brain.step(0.1 * k).force))
    assert not brain.neighbours and not brain.router.table
    assert sum(brain.auth_stats.values()) == len(items)
