"""What a board sent, decoded: shared by the host-firmware and gpsim tests."""

from __future__ import annotations

from swarm_bridge import protocol, xbee

# The coordinator XBee the test builds of the firmware obey (make COORDINATOR=...): the
# host-firmware and gpsim tests send their commands from it.
COORDINATOR = 0x0013A20041FFFF01


def board_messages(data: bytes) -> list:
    """(XBee address, robot message) of every TX request in a board's output bytes."""
    out = []
    for frame_data in xbee.FrameDecoder().feed(data):
        frame = xbee.parse_api_frame(frame_data)
        assert isinstance(frame, xbee.TxRequest)
        out.append((frame.address, protocol.decode_message(frame.data)))
    return out
