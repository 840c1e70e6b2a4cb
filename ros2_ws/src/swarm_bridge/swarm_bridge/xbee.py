"""XBee API mode 2 frame codec (pure; the twin of firmware/src/xbee_parser.c).

A frame is ``0x7E | length (2 bytes) | frame data | checksum``, where the checksum is
``0xFF - (sum of frame data mod 256)``. In API mode 2 (AP=2) every byte after the start
delimiter that equals 0x7E, 0x7D, 0x11 or 0x13 is sent as 0x7D followed by the byte
XOR 0x20, so a raw 0x7E always starts a frame: the decoder resynchronises on it after
garbage, truncated frames and bad checksums, and counts each of them.

Constants come from firmware/include/swarm_protocol.h (a unit test checks they agree).
"""

from __future__ import annotations

from dataclasses import dataclass, field

START = 0x7E
ESCAPE = 0x7D
XON = 0x11
XOFF = 0x13
ESCAPE_XOR = 0x20
CHECKSUM_OK = 0xFF
NEEDS_ESCAPE = frozenset((START, ESCAPE, XON, XOFF))

API_TX_REQUEST = 0x10
API_TX_STATUS = 0x8B
API_RX_PACKET = 0x90
TX_HEADER_LEN = 14
RX_HEADER_LEN = 12
TX_STATUS_LEN = 7
ADDR16_UNKNOWN = 0xFFFE
DELIVERY_OK = 0x00
DELIVERY_NO_ACK = 0x21
DELIVERY_NOT_FOUND = 0x24

# Longest frame data the decoder accepts by default: XBee RF payloads are at most
# 256 bytes, so anything far longer is a corrupted length field.
MAX_FRAME_DATA = 300


class FrameError(ValueError):
    """Frame data that does not parse as the API frame its type byte announces."""


def checksum(data: bytes) -> int:
    """Return the XBee checksum of frame data: 0xFF minus the byte sum modulo 256."""
    return (CHECKSUM_OK - sum(data)) & 0xFF


def escape(data: bytes) -> bytes:
    """Escape 0x7E, 0x7D, 0x11 and 0x13 as 0x7D, byte ^ 0x20 (API mode 2)."""
    out = bytearray()
    for byte in data:
        if byte in NEEDS_ESCAPE:
            out += bytes((ESCAPE, byte ^ ESCAPE_XOR))
        else:
            out.append(byte)
    return bytes(out)


def unescape(data: bytes) -> bytes:
    """Undo :func:`escape`; a trailing lone 0x7D is an error."""
    out = bytearray()
    it = iter(data)
    for byte in it:
        if byte == ESCAPE:
            try:
                byte = next(it) ^ ESCAPE_XOR
            except StopIteration:
                raise FrameError('escape byte 0x7D at the end of the data') from None
        out.append(byte)
    return bytes(out)


def encode_frame(frame_data: bytes) -> bytes:
    """Wrap frame data into an escaped API mode 2 frame (start, length, data, checksum)."""
    if not 0 < len(frame_data) <= 0xFFFF:
        raise FrameError(f'frame data must be 1..65535 bytes, got {len(frame_data)}')
    body = len(frame_data).to_bytes(2, 'big') + bytes(frame_data)
    return bytes((START,)) + escape(body + bytes((checksum(frame_data),)))


@dataclass
class DecoderStats:
    """What a :class:`FrameDecoder` has seen; every count only grows."""

    frames: int = 0
    bad_checksums: int = 0
    truncated: int = 0
    oversize: int = 0
    garbage_bytes: int = 0
    bad_escapes: int = 0   # raw XON/XOFF inside a frame, or an escape of an ordinary byte


@dataclass
class FrameDecoder:
    """Streaming API mode 2 decoder: feed any chunks of bytes, get whole frames' data.

    Mirrors the firmware's state machine: a raw 0x7E restarts the frame (the partial
    frame counts as truncated), lengths of 0 or above ``max_frame_data`` are dropped,
    a bad checksum drops the frame; bytes outside frames count as garbage.
    """

    max_frame_data: int = MAX_FRAME_DATA
    stats: DecoderStats = field(default_factory=DecoderStats)
    _state: str = 'start'
    _escaped: bool = False
    _length: int = 0
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[bytes]:
        """Consume ``data`` and return the frame data of each complete, valid frame."""
        frames = []
        for byte in data:
            frame = self._feed_byte(byte)
            if frame is not None:
                frames.append(frame)
        return frames

    def _feed_byte(self, byte: int) -> bytes | None:
        if byte == START:
            if self._state != 'start':
                self.stats.truncated += 1
            self._state, self._escaped, self._buf = 'len_hi', False, bytearray()
            return None
        if self._state == 'start':
            self.stats.garbage_bytes += 1
            return None
        if byte == ESCAPE:
            self._escaped = True
            return None
        if self._escaped:
            byte ^= ESCAPE_XOR
            self._escaped = False
            if byte not in NEEDS_ESCAPE:
                # Only the four special bytes are ever escaped: a corrupted stream.
                self.stats.bad_escapes += 1
                self._state = 'start'
                return None
        elif byte in (XON, XOFF):
            # API mode 2 never sends XON/XOFF raw inside a frame (a UART would take them
            # for flow control): this is a corrupted escape sequence; drop the frame.
            self.stats.bad_escapes += 1
            self._state = 'start'
            return None
        if self._state == 'len_hi':
            self._length, self._state = byte << 8, 'len_lo'
            if self._length > self.max_frame_data:
                # Too long already (the firmware's 18-byte limit: any nonzero high
                # byte): dropped here, as the firmware does, not at the low byte.
                self.stats.oversize += 1
                self._state = 'start'
        elif self._state == 'len_lo':
            self._length |= byte
            if not 0 < self._length <= self.max_frame_data:
                self.stats.oversize += 1
                self._state = 'start'
            else:
                self._state = 'data'
        elif self._state == 'data':
            self._buf.append(byte)
            if len(self._buf) == self._length:
                self._state = 'checksum'
        else:
            self._state = 'start'
            if (sum(self._buf) + byte) & 0xFF == CHECKSUM_OK:
                self.stats.frames += 1
                return bytes(self._buf)
            self.stats.bad_checksums += 1
        return None


# -- the three API frames the link uses --------------------------------------------------
@dataclass(frozen=True)
class TxRequest:
    """0x10 transmit request: send ``data`` to the radio with 64-bit address ``address``."""

    frame_id: int
    address: int
    data: bytes
    radius: int = 0
    options: int = 0

    def frame_data(self) -> bytes:
        """Return the unframed frame data."""
        return (bytes((API_TX_REQUEST, self.frame_id)) + self.address.to_bytes(8, 'big')
                + ADDR16_UNKNOWN.to_bytes(2, 'big') + bytes((self.radius, self.options))
                + self.data)


@dataclass(frozen=True)
class RxPacket:
    """0x90 receive packet: ``data`` arrived from the radio with 64-bit ``address``."""

    address: int
    data: bytes
    address16: int = ADDR16_UNKNOWN
    options: int = 0x01

    def frame_data(self) -> bytes:
        """Return the unframed frame data."""
        return (bytes((API_RX_PACKET,)) + self.address.to_bytes(8, 'big')
                + self.address16.to_bytes(2, 'big') + bytes((self.options,)) + self.data)


@dataclass(frozen=True)
class TxStatus:
    """0x8B transmit status: delivery report of the 0x10 frame with ``frame_id``."""

    frame_id: int
    delivery: int
    retries: int = 0
    discovery: int = 0
    address16: int = ADDR16_UNKNOWN

    def frame_data(self) -> bytes:
        """Return the unframed frame data."""
        return (bytes((API_TX_STATUS, self.frame_id)) + self.address16.to_bytes(2, 'big')
                + bytes((self.retries, self.delivery, self.discovery)))


ApiFrame = TxRequest | RxPacket | TxStatus


def parse_api_frame(frame_data: bytes) -> ApiFrame:
    """Parse the frame data of a 0x10, 0x90 or 0x8B frame; raise FrameError otherwise."""
    if not frame_data:
        raise FrameError('empty frame data')
    kind = frame_data[0]
    if kind == API_TX_REQUEST and len(frame_data) >= TX_HEADER_LEN:
        return TxRequest(frame_data[1], int.from_bytes(frame_data[2:10], 'big'),
                         bytes(frame_data[TX_HEADER_LEN:]), frame_data[12], frame_data[13])
    if kind == API_RX_PACKET and len(frame_data) >= RX_HEADER_LEN:
        return RxPacket(int.from_bytes(frame_data[1:9], 'big'), bytes(frame_data[RX_HEADER_LEN:]),
                        int.from_bytes(frame_data[9:11], 'big'), frame_data[11])
    if kind == API_TX_STATUS and len(frame_data) == TX_STATUS_LEN:
        return TxStatus(frame_data[1], frame_data[5], frame_data[4], frame_data[6],
                        int.from_bytes(frame_data[2:4], 'big'))
    raise FrameError(f'unsupported API frame type 0x{kind:02X} of {len(frame_data)} bytes')


def encode(frame: ApiFrame) -> bytes:
    """Return ``frame`` as an escaped API mode 2 frame ready for the serial port."""
    return encode_frame(frame.frame_data())
