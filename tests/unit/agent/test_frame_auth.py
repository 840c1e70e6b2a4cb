"""Authenticated radio frames (swarm_agent.frame_auth): seal, open, replay window, keys.

A receiver accepts a frame only when its tag was made under a key it holds, over the
link header and payload as sent, with a counter it has not accepted before from that
source; everything else is dropped and counted by kind.
"""

from __future__ import annotations

import numpy as np
import pytest

from swarm_agent.agent_factory import DEFAULT_KEY_FILE, make_brain, swarm_keyring
from swarm_agent.frame_auth import (
    _accept,
    auth_groups,
    COUNTER_SCALE,
    FrameAuth,
    FrameAuthError,
    Keyring,
    load_keyring,
    new_key_file_text,
    open_all,
    ReplayStore,
    TRAILER_BYTES,
    WINDOW,
)
from swarm_agent.packet import AUTH_TRAILER, BROADCAST, Kind, MAX_BODY, MAX_PAYLOAD, Packet

KEY = Keyring(((1, bytes(range(32))),), seal_id=1)
OTHER = Keyring(((1, bytes(range(1, 33))),), seal_id=1)
T0 = 1.8e9   # a wall-clock time, s


def _clock(t: float = T0):
    return lambda: t


def _frame(payload: bytes = b'\x01\x02hello', source: int = 4) -> Packet:
    return Packet(source, BROADCAST, int(Kind.FLOOD), 77, 32, payload)


def test_seal_then_open_returns_the_frame_and_costs_the_trailer():
    sender, receiver = FrameAuth(KEY, _clock()), FrameAuth(KEY, _clock())
    frame = _frame()
    sealed = sender.seal(frame)
    assert len(sealed.payload) == len(frame.payload) + TRAILER_BYTES == len(frame.payload) + 17
    assert TRAILER_BYTES == AUTH_TRAILER and MAX_BODY + AUTH_TRAILER == MAX_PAYLOAD
    assert receiver.open(sealed) == frame
    assert receiver.stats == {}
    # A full body still fits one XBee payload once sealed.
    assert len(sender.seal(_frame(bytes(MAX_BODY))).payload) == MAX_PAYLOAD


def test_any_tampered_byte_or_header_field_is_rejected():
    sender = FrameAuth(KEY, _clock())
    sealed = sender.seal(_frame())
    receiver = FrameAuth(KEY, _clock())
    for k in range(len(sealed.payload)):
        payload = bytearray(sealed.payload)
        payload[k] ^= 0x01
        forged = Packet(sealed.source, sealed.destination, sealed.kind, sealed.sequence,
                        sealed.ttl, bytes(payload))
        assert receiver.open(forged) is None
    headers = [dict(source=5), dict(destination=9), dict(kind=int(Kind.DATA)),
               dict(sequence=78), dict(ttl=31)]
    for change in headers:
        fields = dict(source=sealed.source, destination=sealed.destination,
                      kind=sealed.kind, sequence=sealed.sequence, ttl=sealed.ttl,
                      payload=sealed.payload) | change
        assert receiver.open(Packet(**fields)) is None
    # Flipping the key-id byte names an unknown key; every other change breaks the tag.
    assert receiver.stats == {'auth_bad_tag': len(sealed.payload) - 1 + len(headers),
                              'auth_unknown_key': 1}
    assert receiver.open(sealed) is not None   # the genuine frame still passes


def test_wrong_key_short_frames_and_unknown_key_ids_are_rejected_and_counted():
    receiver = FrameAuth(KEY, _clock())
    assert receiver.open(FrameAuth(OTHER, _clock()).seal(_frame())) is None
    assert receiver.open(_frame(bytes(TRAILER_BYTES - 1))) is None
    rotated = Keyring(((1, bytes(range(32))), (2, bytes(32))), seal_id=2)
    assert receiver.open(FrameAuth(rotated, _clock()).seal(_frame())) is None
    assert receiver.stats == {'auth_bad_tag': 1, 'auth_short': 1, 'auth_unknown_key': 1}
    # Rotation: a receiver holding both keys accepts frames sealed under either.
    both = FrameAuth(rotated, _clock())
    assert both.open(FrameAuth(KEY, _clock()).seal(_frame())) is not None
    assert both.open(FrameAuth(rotated, _clock()).seal(_frame(source=5))) is not None


def test_replays_are_rejected_and_reordering_inside_the_window_is_not():
    sender, receiver = FrameAuth(KEY, _clock()), FrameAuth(KEY, _clock())
    sealed = [sender.seal(_frame(bytes([k]))) for k in range(WINDOW + 3)]
    assert receiver.open(sealed[1]) is not None
    assert receiver.open(sealed[1]) is None              # replay
    assert receiver.open(sealed[0]) is not None          # late, inside the window
    assert receiver.open(sealed[0]) is None              # and only once
    assert receiver.open(sealed[-1]) is not None         # the window moves on
    assert receiver.open(sealed[2]) is None              # 64 + 0 below the highest: too old
    assert receiver.open(sealed[3]) is not None          # 63 below: still inside
    assert receiver.stats == {'auth_replay': 2, 'auth_too_old': 1}


def test_windows_are_per_source():
    receiver = FrameAuth(KEY, _clock())
    a, b = FrameAuth(KEY, _clock(T0 + 100.0)), FrameAuth(KEY, _clock())
    assert receiver.open(a.seal(_frame(source=4))) is not None
    # Source 5's counters are far below source 4's: its own window decides.
    assert receiver.open(b.seal(_frame(source=5))) is not None
    assert receiver.stats == {}


@pytest.mark.usefixtures('kernels')
def test_replay_window_bitmap():
    """A window of 4 below the highest counter: 0 accepted, 1 a replay, 2 too old."""
    store = ReplayStore()
    rows, col = np.array([store.add_row()]), store.column_of(1)
    results = [_accept(store.cells, rows, col, np.uint64(c), np.uint64(4),
                       np.uint64(0b1111)) for c in (10, 8, 8, 12, 9, 8, 6)]
    assert [int(verdict[0]) for verdict, _ in results] == [0, 0, 1, 0, 0, 2, 2]
    assert [int(refused) for _, refused in results] == [0, 0, 1, 0, 0, 1, 1]


@pytest.mark.usefixtures('kernels')
def test_counters_near_two_to_the_64_stay_exact():
    """Counters are unsigned 64-bit: the window works at the top of the range, where a
    float would merge neighbouring counters."""
    store = ReplayStore()
    rows, col = np.array([store.add_row()]), store.column_of(9)
    top = (1 << 64) - 3
    verdicts = [int(_accept(store.cells, rows, col, np.uint64(c), np.uint64(64),
                            np.uint64((1 << 64) - 1))[0][0])
                for c in (top, top + 1, top, top - 1)]
    assert verdicts == [0, 0, 1, 0]
    assert int(store.cells[0, col, 0]) == top + 1


@pytest.mark.usefixtures('kernels')
def test_one_frame_opened_by_many_receivers_as_one_by_one():
    """``open_all`` gives each receiver what its own ``open`` would: receivers that heard
    the frame already reject a replay, a receiver under another key rejects the tag, the
    rest accept; a second store and another window size are grouped apart."""
    sender = FrameAuth(KEY, _clock())
    frames = [sender.seal(_frame()) for _ in range(3)]
    store = ReplayStore()

    def receivers():
        return [FrameAuth(KEY, _clock(), store=store), FrameAuth(KEY, _clock(), store=store),
                FrameAuth(OTHER, _clock(), store=store), FrameAuth(KEY, _clock()),
                FrameAuth(KEY, _clock(), window=1, store=store)]
    together, alone = receivers(), receivers()
    kept = receivers()                                     # their groups worked out once
    groups = auth_groups(kept)
    assert sorted(i for group, _ in groups for i in group) == list(range(5))
    assert len(groups) == 4       # the two of one store, key and window are one group
    for auths in (together, alone, kept):
        auths[1].open(frames[2])                           # receiver 1 heard a later one
    for frame in (frames[0], frames[2], frames[1]):
        expected = [a.open(frame) for a in alone]
        assert open_all(together, frame) == expected
        assert open_all(kept, frame, groups) == expected
    assert [a.stats for a in together] == [a.stats for a in alone] == [
        a.stats for a in kept] == [
        {}, {'auth_replay': 1}, {'auth_bad_tag': 3}, {}, {'auth_too_old': 1}]


def test_a_forged_frame_does_not_move_the_window():
    sender, receiver = FrameAuth(KEY, _clock()), FrameAuth(KEY, _clock())
    genuine = sender.seal(_frame())
    forger = FrameAuth(OTHER, _clock(T0 + 1e6))    # far-future counter, wrong key
    assert receiver.open(forger.seal(_frame())) is None
    assert receiver.open(genuine) is not None


def test_a_restarted_sender_counts_above_its_old_run():
    """Counter = boot time in 2**-20 s + frames since boot: a run that sealed a million
    frames in 10 s, restarted 1 s after it stopped, starts above its last counter, and
    a receiver that kept its window accepts it."""
    old = FrameAuth(KEY, _clock(T0))
    receiver = FrameAuth(KEY, _clock())
    last = None
    for _ in range(3):
        last = old.seal(_frame())
    old._counter += 10 ** 6 - 3          # as if it had sealed a million frames
    last = old.seal(_frame())
    assert receiver.open(last) is not None
    restarted = FrameAuth(KEY, _clock(T0 + 11.0))
    first = restarted.seal(_frame())
    assert restarted.counter > old.counter
    assert restarted.counter == round((T0 + 11.0) * COUNTER_SCALE)
    assert receiver.open(first) is not None
    assert receiver.stats == {}


def test_key_files(tmp_path):
    ring = swarm_keyring()
    assert ring.development and ring.key(ring.seal_id) is not None
    assert swarm_keyring(str(DEFAULT_KEY_FILE)) is ring   # loaded once per process
    path = tmp_path / 'keys.yaml'
    path.write_text(new_key_file_text(7))
    fresh = load_keyring(str(path))
    assert fresh.seal_id == 7 and not fresh.development and len(fresh.key(7)) == 32
    bad = {'missing.yaml': None, 'empty.yaml': '', 'short.yaml': 'seal: 1\nkeys: {1: abcd}\n',
           'hex.yaml': 'seal: 1\nkeys: {1: zz}\n', 'seal.yaml': new_key_file_text(3)
           .replace('seal: 3', 'seal: 4')}
    for name, text in bad.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        with pytest.raises(FrameAuthError, match=name) as err:
            load_keyring(str(tmp_path / name))
        assert '\n' not in str(err.value) and 'swarm_key_file' in str(err.value)


def test_brains_seal_what_they_send_and_drop_what_fails():
    """Two brains under the development key hear each other; a brain without it (a
    rogue) is not heard, and its frames are counted as bad tags."""
    a = make_brain(agent_id=1, agent_type=1, initial_position=(0.0, 0.0))
    b = make_brain(agent_id=2, agent_type=1, initial_position=(1.0, 0.0))
    rogue = make_brain(agent_id=3, agent_type=1, initial_position=(0.5, 0.0),
                       keyring=OTHER)
    for k in range(8):
        t = 0.5 * k
        for sender in (a, b, rogue):
            for packet in sender.step(t).packets:
                assert len(packet.payload) <= MAX_PAYLOAD
                for receiver in (a, b, rogue):
                    if receiver is not sender:
                        receiver.on_packet(t, packet)
    assert set(a.neighbours) == {2} and set(b.neighbours) == {1}
    assert set(rogue.neighbours) == set()
    assert a.auth_stats['auth_bad_tag'] > 0 and 'auth_bad_tag' in a.status_line()
    plain = make_brain(agent_id=4, agent_type=1, auth=False)
    assert plain.auth is None and plain.auth_stats == {}


def test_a_frame_sealed_here_opens_without_its_tag_computed_again(monkeypatch):
    """The seal enters its frame in the verified frames: a receiver holding the key opens
    it with no HMAC of its own; the same header with a forged tag, or with the body
    changed after sealing, is still computed and rejected."""
    from swarm_agent import frame_auth
    sender, receiver = FrameAuth(KEY, _clock()), FrameAuth(KEY, _clock())
    sealed = sender.seal(_frame(b'sealed here'))
    tags = []
    real = frame_auth._tag
    monkeypatch.setattr(frame_auth, '_tag', lambda key, data: tags.append(1) or real(key, data))
    assert receiver.open(sealed) == _frame(b'sealed here') and tags == []
    body = sealed.payload
    forged = Packet(*[getattr(sealed, f) for f in ('source', 'destination', 'kind', 'sequence',
                                                   'ttl')], body[:-1] + bytes([body[-1] ^ 1]))
    changed = Packet(sealed.source, sealed.destination, sealed.kind, sealed.sequence,
                     sealed.ttl, b'X' + body[1:])
    assert receiver.open(forged) is None and receiver.open(changed) is None
    assert len(tags) == 2 and receiver.stats == {'auth_bad_tag': 2}
    # Under another keyring the sealed frame is checked, and fails.
    assert FrameAuth(OTHER, _clock()).open(sealed) is None and len(tags) == 3
