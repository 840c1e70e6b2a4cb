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


def test_a_sensor_batch_carries_each_robots_part_of_a_step():
    pytest.importorskip('swarm_msgs')
    from builtin_interfaces.msg import Time
    import numpy as np

    from swarm_agent.conversions import sensor_batch_from_msg, sensor_batch_to_msg
    from swarm_msgs.msg import RangeArray, RangeMeasurement

    stamp = Time(sec=12, nanosec=500_000_000)
    ranges = [RangeArray(receiver=4, ranges=[RangeMeasurement(beacon_id=1, range=3.5,
                                                              stddev=0.1)])]
    frames = _frames()
    # Deliveries grouped by frame, in arrival order, as RadioMedium.deliver_grouped.
    (s0, f0), (s1, f1), (s2, f2) = frames
    grouped = [(s0, f0, [11, 4]), (s1, f1, [4]), (s2, f2, [11, 4, 9])]
    # Robot 4 sees two neighbours, robot 11 nobody, robot 9 one.
    msg = sensor_batch_to_msg(stamp, imu_ids=[4, 9], imu_accel=np.array([[0.1, -0.2],
                                                                         [0.0, 0.3]]),
                              imu_noise_std=0.01, ranges=ranges, prox_ids=[4, 11, 9],
                              prox_counts=[2, 0, 1],
                              prox_offsets=[[1.5, -0.5], [0.0, 2.0], [-1.5, 0.5]],
                              prox_radii=[0.4, 0.15, 0.3], prox_stddev=0.02, rx=grouped,
                              gps=[(1, -3.0, 4.5, 2.0)])
    imu, got_ranges, scans, rx, gps = sensor_batch_from_msg(msg)
    assert imu == [(4, 0.1, -0.2), (9, 0.0, 0.3)] and msg.imu_noise_std == 0.01
    assert gps == [(1, -3.0, 4.5, 2.0)]
    assert got_ranges[0].receiver == 4 and got_ranges[0].ranges[0].range == 3.5
    assert sorted(scans) == [4, 9, 11] and msg.prox_stddev == 0.02
    assert scans[4][0].tolist() == [[1.5, -0.5], [0.0, 2.0]]
    assert scans[4][1].tolist() == [0.4, 0.15]
    assert scans[9][0].tolist() == [[-1.5, 0.5]] and scans[9][1].tolist() == [0.3]
    assert scans[11][0].shape == (0, 2) and scans[11][1].shape == (0,)
    # Counts that disagree with the rows are refused, naming both.
    msg.prox_counts = [2, 0, 2]
    with pytest.raises(PacketError, match='summing to 4 but 3 x'):
        sensor_batch_from_msg(msg)
    msg.prox_counts = [2, 0, 1]
    # Grouped by frame again, in arrival order: each receiver's frames keep their order.
    assert rx == [(s0, f0, [4, 11]), (s1, f1, [4]), (s2, f2, [4, 9, 11])]
    # Each frame travels once, whatever the number of its receivers.
    assert len(msg.rx_frames) == 6 and len(msg.frames) == len(pack_frames(frames))
    empty = sensor_batch_to_msg(stamp)            # nothing due this step
    assert sensor_batch_from_msg(empty) == ([], [], {}, [], [])
    # Arrays that disagree, or a receiver's bytes cut short, are refused, never misread.
    every = [(s, f, [4]) for s, f in frames]
    short = sensor_batch_to_msg(stamp, rx=every)
    short.rx_counts = [short.rx_counts[0] + 1]
    with pytest.raises(PacketError, match='summing to 4 frames, 3 indices'):
        sensor_batch_from_msg(short)
    wild = sensor_batch_to_msg(stamp, rx=every)
    wild.rx_frames = [0, 1, 3]
    with pytest.raises(PacketError, match='frame index 3 beyond the 3 frames'):
        sensor_batch_from_msg(wild)
    cut = sensor_batch_to_msg(stamp, rx=every)
    cut.frames = cut.frames[:-1]
    with pytest.raises(PacketError, match='truncated frame header'):
        sensor_batch_from_msg(cut)
    lopsided = sensor_batch_to_msg(stamp, imu_ids=[4], imu_accel=[[0.1, 0.2]])
    lopsided.imu_ay = [0.2, 0.3]
    with pytest.raises(PacketError, match='1 imu ids but 1 x and 2 y'):
        sensor_batch_from_msg(lopsided)
    fixless = sensor_batch_to_msg(stamp, gps=[(1, 0.0, 0.0, 2.0)])
    fixless.gps_std = []
    with pytest.raises(PacketError, match='1 gps ids but 1 x, 1 y and 0 std'):
        sensor_batch_from_msg(fixless)


def test_a_proximity_scan_round_trips_and_a_lopsided_one_is_refused():
    pytest.importorskip('swarm_msgs')
    from builtin_interfaces.msg import Time
    import numpy as np

    from swarm_agent.conversions import (
        proximity_from_msg,
        proximity_to_msg,
        SensorMessageError,
    )

    stamp = Time(sec=7, nanosec=250_000_000)
    offsets = np.array([[0.5, -1.25], [-2.0, 0.125], [1e-3, 2.9]])
    radii = np.array([0.3, 0.45, 0.6])
    msg = proximity_to_msg(stamp, 42, offsets, radii, 0.02)
    assert msg.header.stamp == stamp and msg.receiver == 42 and msg.stddev == 0.02
    assert list(msg.x) == [0.5, -2.0, 1e-3] and list(msg.y) == [-1.25, 0.125, 2.9]
    got_offsets, got_radii = proximity_from_msg(msg)
    np.testing.assert_array_equal(got_offsets, offsets)
    np.testing.assert_array_equal(got_radii, radii)
    assert got_offsets.shape == (3, 2) and got_radii.shape == (3,)
    # Arrays that disagree are refused with their lengths, never paired up wrongly.
    msg.radius = [0.3, 0.45]
    with pytest.raises(SensorMessageError, match='robot 42: 3 x, 3 y and 2 radius'):
        proximity_from_msg(msg)
    msg = proximity_to_msg(stamp, 42, offsets, radii, 0.02)
    msg.y = [0.0]
    with pytest.raises(ValueError, match='3 x, 1 y and 3 radius'):
        proximity_from_msg(msg)
