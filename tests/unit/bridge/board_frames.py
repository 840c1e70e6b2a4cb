"""What a board sent, decoded: shared by the host-firmware and gpsim tests."""

from __future__ import annotations

from swarm_bridge import protocol, xbee


def board_messages(data: bytes) -> list:
    """(XBee address, robot message) of every TX request in a board's output bytes."""
    out = []
    for frame_data in xbee.FrameDecoder().feed(data):
        frame = xbee.parse_api_frame(frame_data)
        assert isinstance(frame, xbee.TxRequest)
        out.append((frame.address, protocol.decode_message(frame.data)))
    return out
