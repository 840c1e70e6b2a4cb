"""Packed radio frames (swarm_msgs/RadioPacketArray.frames): lossless and strict."""

import pytest

from swarm_agent.packet import (
    BROADCAST,
    Kind,
    MAX_PAYLOAD,
    pack_frames,
    Packet,
    PacketError,
    unpack_frames,
)


def _frames():
    return [
        (12.25, Packet(3, BROADCAST, Kind.HEARTBEAT, 65535, 1, b'\x01\x02\x03')),
        (12.5, Packet(65534, 7, Kind.DATA, 0, 255, bytes(range(MAX_PAYLOAD)))),
        (1e6 + 0.125, Packet(0, 1, Kind.FRAGMENT, 42, 8, b'')),
    ]


def test_frames_round_trip_field_by_field():
    data = pack_frames(_frames())
    # 17-byte header per frame plus the payloads: nothing else on the wire.
    assert len(data) == 3 * 17 + 3 + MAX_PAYLOAD
    assert unpack_frames(data) == _frames()
    assert unpack_frames(pack_frames([])) == []


def test_unpack_accepts_what_rosidl_keeps_for_uint8_arrays():
    from array import array

    assert unpack_frames(array('B', pack_frames(_frames()))) == _frames()


@pytest.mark.parametrize('cut', [1, 16, 17 + 2])
def test_truncated_batches_are_rejected_with_the_offset(cut):
    data = pack_frames(_frames()[:1])
    with pytest.raises(PacketError, match='at byte 0'):
        unpack_frames(data[:cut])


def test_a_frame_with_a_lying_length_is_rejected():
    data = bytearray(pack_frames(_frames()[:1]))
    data[16] = 200  # announce 200 payload bytes, 3 follow
    with pytest.raises(PacketError, match='announces 200 payload bytes, 3 left'):
        unpack_frames(bytes(data))


def test_oversize_payload_cannot_be_packed():
    with pytest.raises(PacketError, match='256 bytes from 4'):
        pack_frames([(0.0, Packet(4, 5, Kind.DATA, 1, 1, bytes(256)))])


def test_a_corrupt_batch_is_dropped_with_one_line_naming_the_topic():
    pytest.importorskip('swarm_msgs')
    from swarm_agent.conversions import frames_from_msg, frames_or_log, frames_to_msg

    class Logger:
        def __init__(self):
            self.lines = []

        def error(self, text, **_):
            self.lines.append(text)

    good = frames_to_msg(_frames())
    assert frames_from_msg(good) == _frames()
    bad = frames_to_msg(_frames())
    bad.frames = bad.frames[:19]  # the first frame's header, then 2 of its 3 payload bytes
    logger = Logger()
    assert frames_or_log(bad, logger, '/radio/tx') == []
    assert len(logger.lines) == 1 and '/radio/tx' in logger.lines[0]
    assert 'announces 3 payload bytes, 2 left' in logger.lines[0]
    assert frames_or_log(good, logger, '/radio/tx') == _frames()


def test_one_frame_heard_by_many_is_decoded_once_and_keeps_each_stamp():
    # A broadcast reaches every neighbour; in a composed process the receivers share the
    # frozen Packet (decoded once) but each keeps its own delivery stamp.
    frame = Packet(3, BROADCAST, Kind.HEARTBEAT, 41, 1, b'\x01\x02\x03')
    (t1, a), = unpack_frames(pack_frames([(10.25, frame)]))
    (t2, b), = unpack_frames(pack_frames([(10.75, frame)]))
    assert (t1, t2) == (10.25, 10.75) and a == b == frame and a is b
    other = Packet(4, BROADCAST, Kind.HEARTBEAT, 41, 1, b'\x01\x02\x03')  # another sender
    (_, c), = unpack_frames(pack_frames([(10.25, other)]))
    assert c == other and c.source == 4
