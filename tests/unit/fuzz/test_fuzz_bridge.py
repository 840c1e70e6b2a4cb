"""Fuzzing of the robot link: XBee API frames, robot messages, the bridge and the board.

The serial line delivers arbitrary bytes (noise, truncated or corrupted frames, frames
from strangers). ``xbee`` may raise only ``FrameError``, ``protocol`` only
``MessageError``; the streaming decoder, the ``Bridge`` and the emulated board never
raise and count what they drop. Valid encodings round-trip; the decoder's output does
not depend on how the stream is chunked, and it resynchronises on the next frame.
"""

from __future__ import annotations

from hypothesis import example, given, HealthCheck, settings
from hypothesis import strategies as st

from swarm_bridge import emulator, protocol, xbee
from swarm_bridge.bridge import Bridge
from swarm_common.fleet import load_fleet

FUZZ = settings(max_examples=200, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])
U8 = st.integers(0, 0xFF)
U16 = st.integers(0, 0xFFFF)
U64 = st.integers(0, 2 ** 64 - 1)


# ---------------------------------------------------------------------------- xbee
@FUZZ
@given(st.binary(max_size=400))
@example(b'\x7d')                                   # lone escape
@example(b'\x7e\x00\x00')                           # zero length
@example(b'\x7e\xff\xff' + bytes(10))               # oversize length
@example(b'\x7e\x00\x02\x7d\x7e\x01\x00')           # escape followed by a raw start
def test_frame_decoder_never_raises_and_counts(data):
    decoder = xbee.FrameDecoder()
    frames = decoder.feed(data)
    assert decoder.stats.frames == len(frames)
    for frame in frames:
        assert 0 < len(frame) <= xbee.MAX_FRAME_DATA


@FUZZ
@given(st.binary(max_size=300), st.lists(st.integers(0, 300), max_size=6))
def test_frame_decoder_does_not_depend_on_chunking(data, cuts):
    whole = xbee.FrameDecoder()
    expected = whole.feed(data)
    split = xbee.FrameDecoder()
    got = []
    start = 0
    for cut in sorted(cuts) + [len(data)]:
        got += split.feed(data[start:max(start, cut)])
        start = max(start, cut)
    assert got == expected and split.stats == whole.stats


frames = st.one_of(
    st.builds(xbee.TxRequest, U8, U64, st.binary(max_size=100), U8, U8),
    st.builds(xbee.RxPacket, U64, st.binary(max_size=100), U16, U8),
    st.builds(xbee.TxStatus, U8, U8, U8, U8, U16))


@FUZZ
@given(st.binary(max_size=200), frames)
def test_decoder_resynchronises_after_garbage(garbage, frame):
    decoder = xbee.FrameDecoder()
    got = decoder.feed(garbage + xbee.encode(frame))
    assert got and got[-1] == frame.frame_data()
    assert xbee.parse_api_frame(got[-1]) == frame


@FUZZ
@given(st.binary(max_size=120))
def test_api_frame_parser_and_unescape_raise_only_frame_error(data):
    try:
        xbee.parse_api_frame(data)
    except xbee.FrameError as exc:
        assert str(exc)
    try:
        assert xbee.escape(xbee.unescape(data)) is not None
    except xbee.FrameError as exc:
        assert str(exc)
    assert xbee.unescape(xbee.escape(data)) == data


# ---------------------------------------------------------------------------- protocol
@FUZZ
@given(st.binary(max_size=20))
@example(bytes([protocol.MSG_CMD_VEL, 1, 0, 10, 0x01, 0x68]))   # direction 360
@example(bytes([protocol.MSG_STATUS]))
def test_robot_message_decoder_raises_only_message_error(data):
    try:
        msg = protocol.decode_message(data)
    except protocol.MessageError as exc:
        assert str(exc)
    else:
        assert msg.encode() == bytes(data)


messages = st.one_of(
    st.builds(protocol.CmdVel, U8, U16, st.integers(0, 359)),
    st.builds(protocol.Stop, U8),
    st.builds(protocol.Status, U8, U8, U16,
              st.tuples(*[st.integers(-0x8000, 0x7FFF)] * 3), U8, U8),
    st.builds(protocol.Ack, U8, U8, U8))


@FUZZ
@given(messages)
def test_robot_messages_round_trip(msg):
    assert protocol.decode_message(msg.encode()) == msg


# ---------------------------------------------------------------------------- endpoints
def _stream(addresses: list[int]) -> st.SearchStrategy[bytes]:
    """Noise mixed with well-formed frames from known and unknown radios."""
    rf = st.one_of(messages.map(lambda m: m.encode()), st.binary(max_size=16))
    rx = st.builds(lambda a, d: xbee.encode(xbee.RxPacket(a, d)),
                   st.one_of(st.sampled_from(addresses), U64), rf)
    other = frames.map(xbee.encode)
    corrupt = st.builds(lambda f, k, b: f[:k] + bytes([b]) + f[k + 1:], rx,
                        st.integers(0, 30), U8)
    piece = st.one_of(rx, other, corrupt, st.binary(max_size=30))
    return st.lists(piece, max_size=12).map(b''.join)


ROBOTS = load_fleet()


@FUZZ
@given(st.lists(_stream([r.address for r in ROBOTS]), max_size=4))
def test_bridge_never_raises_on_serial_noise(chunks):
    bridge = Bridge(ROBOTS)
    for k, chunk in enumerate(chunks):
        updated = bridge.on_bytes(chunk, 0.1 * k)
        assert set(updated) <= set(bridge.links)
        bridge.poll(0.1 * k)
    assert all(v >= 0 for v in bridge.counters.values())
    bridge.take_events()


@FUZZ
@given(st.lists(_stream([0, 0x0013A200DEADBEEF]), max_size=4))
def test_emulated_board_never_raises_on_uart_noise(chunks):
    board = emulator.EmulatedBoard(1)
    for chunk in chunks:
        board.receive(chunk)
        board.tick(5)
        assert all(abs(r) <= protocol.MAX_STEP_RATE for r in board.rates)
    board.transmit()
