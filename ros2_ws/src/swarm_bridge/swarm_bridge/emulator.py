"""Emulated robots behind an emulated coordinator XBee, for hardware-in-the-loop runs
without hardware.

- :class:`EmulatedBoard` is a Python twin of the firmware (firmware/src/robot.c): it
  receives escaped 0x90 frames, obeys only those from its ``coordinator`` address (the
  firmware's SWP_COORDINATOR_ADDR64) and drops the others unanswered, counting them
  (status ``foreign``, fault FAULT_FOREIGN), mixes CmdVel with the fixed-point mixer (eqs. 5.1-5.3,
  bit-exact with the C), acknowledges, stops its wheels SWP_CMD_TIMEOUT_MS after the last
  valid command and sends a status every SWP_HEARTBEAT_MS, as 0x10 frames. Every
  half-step a wheel takes moves the robot: the board integrates the forward kinematics
  of eqs. 5.1-5.3 (:func:`step_displacement`) into a map-frame pose, which is what the
  overhead camera of thesis 5.1 sees (:mod:`swarm_bridge.hil_world_node` publishes it).
- :class:`EmulatedRadio` stands for the XBee network: it takes the host's 0x10 frames,
  delivers them to the board with that 64-bit address as 0x90 frames from the
  ``coordinator`` address (0x8B status 0x24 when there is none, 0x21 when the board is
  powered off), and hands boards' frames to the host as 0x90 frames from their address.
  :meth:`EmulatedRadio.inject` is another XBee in range transmitting to a board.
- :func:`main` (console script ``robot_emulator``) serves the fleet on a pseudo-terminal
  whose path it prints: point bridge_node's ``port`` parameter at it. Its boards obey
  the fleet file's ``coordinator``, as the firmware built from that file does.

Time is an argument (milliseconds), so tests are deterministic.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import math
import os
import select
import sys
import time
import tty

from swarm_bridge import protocol, xbee
from swarm_common.fleet import FleetError, load_coordinator, load_fleet

FIRMWARE_MAX_FRAME_DATA = 18   # SWP_MAX_FRAME_DATA
BASE_RADIUS_M = 0.06           # wheel contact to robot centre (assumed: the thesis names none)


def step_displacement(wheel: int, direction: int,
                      base_radius: float = BASE_RADIUS_M) -> tuple[float, float, float]:
    """Body-frame motion (dx forward m, dy left m, dyaw rad CCW) of one half-step.

    Forward kinematics of eqs. 5.1-5.3: the body velocity is the least-squares inverse
    ``(2/3) sum V_i d_i`` (protocol.body_velocity_from_wheels), so one half-step of wheel
    ``i`` (a surface travel of 1/HALF_STEPS_PER_M) moves the body by 2/3 of it along the
    wheel's drive direction d_i. The drive directions are tangential and 120 degrees
    apart, so the wheels' mean travel turns the body: ``dyaw = -travel / (3 r)`` (a
    positive wheel speed drives clockwise; with eqs. 5.1-5.3 the three terms cancel and
    only step quantisation turns the robot, by a bounded amount).
    """
    travel = direction / protocol.HALF_STEPS_PER_M
    phi = math.radians(protocol.WHEEL_PHI[wheel])
    return (2.0 / 3.0 * travel * math.cos(phi), -2.0 / 3.0 * travel * math.sin(phi),
            -travel / (3.0 * base_radius))


_STEPS = {(w, d): step_displacement(w, d) for w in range(3) for d in (1, -1)}


@dataclass
class EmulatedBoard:
    """A PIC16F690 board running the firmware's logic; see the module docstring."""

    address: int
    coordinator: int = 0           # the only sender obeyed; statuses and acks go there
    powered: bool = True
    rates: list[int] = field(default_factory=lambda: [0, 0, 0])
    positions: list[int] = field(default_factory=lambda: [0, 0, 0])
    cmd_age_ms: int = 0xFFFF
    faults: int = protocol.FAULT_RESET
    last_cmd_seq: int = 0
    status_seq: int = 0
    commands: int = 0
    foreign: int = 0               # 0x90 frames dropped: not from the coordinator
    x: float = 0.0                 # map-frame pose (m, m, rad CCW): the camera's view
    y: float = 0.0
    yaw: float = 0.0
    _acc: list[int] = field(default_factory=lambda: [0, 0, 0])
    _heartbeat_ms: int = 0
    _running: bool = False
    _out: bytearray = field(default_factory=bytearray)
    _parser: xbee.FrameDecoder = field(
        default_factory=lambda: xbee.FrameDecoder(FIRMWARE_MAX_FRAME_DATA))

    def receive(self, data: bytes) -> None:
        """Bytes arriving on the board's UART from its XBee."""
        if not self.powered:
            return
        stats = self._parser.stats
        before = stats.bad_checksums + stats.truncated + stats.oversize
        for frame_data in self._parser.feed(data):
            self._handle(frame_data)
        if stats.bad_checksums + stats.truncated + stats.oversize != before:
            self.faults |= protocol.FAULT_BAD_FRAME

    def _send(self, message: protocol.Message) -> None:
        self._out += xbee.encode(xbee.TxRequest(0, self.coordinator, message.encode()))

    def _handle(self, frame_data: bytes) -> None:
        if frame_data[0] != xbee.API_RX_PACKET or len(frame_data) < xbee.RX_HEADER_LEN:
            return
        frame = xbee.parse_api_frame(frame_data)
        if frame.address != self.coordinator:
            self.foreign += 1            # dropped unanswered, as robot.c's handle_frame
            self.faults |= protocol.FAULT_FOREIGN
            return
        data = frame.data
        if len(data) < 2:
            return
        try:
            msg = protocol.decode_message(data)
        except protocol.MessageError:
            self.faults |= protocol.FAULT_BAD_MSG
            lengths = {protocol.MSG_CMD_VEL: protocol.LEN_CMD_VEL,
                       protocol.MSG_STOP: protocol.LEN_STOP}
            if data[0] not in lengths:
                result = protocol.ACK_UNKNOWN_TYPE
            elif len(data) != lengths[data[0]]:
                result = protocol.ACK_BAD_LENGTH
            else:
                result = protocol.ACK_BAD_VALUE
            self._send(protocol.Ack(data[1], data[0], result))
            return
        if isinstance(msg, protocol.CmdVel):
            rates, clipped = protocol.mix_fixed(msg.speed, msg.direction)
            if clipped:
                self.faults |= protocol.FAULT_RATE_LIMIT
            self._apply(list(rates))
        elif isinstance(msg, protocol.Stop):
            self._apply([0, 0, 0])
        else:
            self.faults |= protocol.FAULT_BAD_MSG
            self._send(protocol.Ack(data[1], data[0], protocol.ACK_UNKNOWN_TYPE))
            return
        self.commands += 1
        self.last_cmd_seq = msg.seq
        self._send(protocol.Ack(msg.seq, data[0], protocol.ACK_OK))

    def _apply(self, rates: list[int]) -> None:
        self.rates = rates
        self._running = any(rates)
        self.cmd_age_ms = 0
        self.faults &= ~protocol.FAULT_WATCHDOG & 0xFF

    def tick(self, ms: int = 1) -> None:
        """Advance ``ms`` timer ticks: watchdog, heartbeat, step timing."""
        if not self.powered:
            return
        for _ in range(ms):
            self.cmd_age_ms = min(0xFFFF, self.cmd_age_ms + 1)
            if self._running and self.cmd_age_ms >= protocol.CMD_TIMEOUT_MS:
                self.rates = [0, 0, 0]
                self._running = False
                self.faults |= protocol.FAULT_WATCHDOG
            self._heartbeat_ms += 1
            if self._heartbeat_ms >= protocol.HEARTBEAT_MS:
                self._heartbeat_ms = 0
                self._heartbeat()
            for i, rate in enumerate(self.rates):
                if rate:
                    self._acc[i] += abs(rate)
                    if self._acc[i] >= protocol.TICK_HZ:
                        self._acc[i] -= protocol.TICK_HZ
                        self._step(i, 1 if rate > 0 else -1)

    def _step(self, wheel: int, direction: int) -> None:
        """One half-step of ``wheel``: count it and move the body (step_displacement)."""
        self.positions[wheel] += direction
        dx, dy, dyaw = _STEPS[(wheel, direction)]
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        self.x += c * dx - s * dy
        self.y += s * dx + c * dy
        self.yaw = math.remainder(self.yaw + dyaw, math.tau)

    def place(self, x: float, y: float, yaw: float) -> None:
        """Put the robot at a map-frame pose (m, m, rad counter-clockwise)."""
        self.x, self.y, self.yaw = float(x), float(y), float(yaw)

    def pose(self) -> tuple[float, float, float]:
        """The robot's map-frame pose (x m, y m, yaw rad CCW), as the camera sees it."""
        return self.x, self.y, self.yaw

    def _heartbeat(self) -> None:
        stats = self._parser.stats
        bad = (stats.bad_checksums + stats.truncated + stats.oversize) & 0xFF
        self._send(protocol.Status(self.status_seq, self.last_cmd_seq, self.cmd_age_ms,
                                   tuple(self.rates), self.faults, bad, self.foreign & 0xFF))
        self.status_seq = (self.status_seq + 1) & 0xFF
        self.faults &= protocol.FAULT_STICKY

    def transmit(self) -> bytes:
        """Return and forget the bytes the board sent to its XBee."""
        out, self._out = bytes(self._out), bytearray()
        return out

    def wheel_speeds(self) -> tuple[float, float, float]:
        """Wheel surface speeds (m/s) of the current step rates."""
        return tuple(r / protocol.HALF_STEPS_PER_M for r in self.rates)


@dataclass
class EmulatedRadio:
    """The XBee network between the host's coordinator radio and the boards."""

    boards: dict[int, EmulatedBoard]
    coordinator: int = 0
    _host_in: xbee.FrameDecoder = field(default_factory=xbee.FrameDecoder)
    _board_in: dict[int, xbee.FrameDecoder] = field(default_factory=dict)
    _to_host: bytearray = field(default_factory=bytearray)

    @classmethod
    def for_fleet(cls, addresses: list[int], coordinator: int = 0) -> EmulatedRadio:
        """One powered board per address, each built for ``coordinator``."""
        return cls({a: EmulatedBoard(a, coordinator) for a in addresses}, coordinator)

    def inject(self, source: int, destination: int, data: bytes) -> None:
        """Another XBee in range, with 64-bit address ``source``, sends RF ``data`` to the
        board ``destination`` (a rogue transmitter, or a second host)."""
        board = self.boards.get(destination)
        if board is not None and board.powered:
            board.receive(xbee.encode(xbee.RxPacket(source, data)))

    def from_host(self, data: bytes) -> None:
        """Bytes the host wrote to its XBee."""
        for frame_data in self._host_in.feed(data):
            try:
                frame = xbee.parse_api_frame(frame_data)
            except xbee.FrameError:
                continue
            if not isinstance(frame, xbee.TxRequest):
                continue
            board = self.boards.get(frame.address)
            if board is None:
                status = xbee.DELIVERY_NOT_FOUND
            elif not board.powered:
                status = xbee.DELIVERY_NO_ACK
            else:
                status = xbee.DELIVERY_OK
                board.receive(xbee.encode(xbee.RxPacket(self.coordinator, frame.data)))
            if frame.frame_id:
                self._to_host += xbee.encode(xbee.TxStatus(frame.frame_id, status))

    def advance(self, ms: int) -> None:
        """Run every board for ``ms`` milliseconds, relaying what they send."""
        for _ in range(ms):
            for address, board in self.boards.items():
                board.tick(1)
                self._relay(address, board.transmit())

    def _relay(self, address: int, data: bytes) -> None:
        if not data:
            return
        decoder = self._board_in.setdefault(address, xbee.FrameDecoder())
        for frame_data in decoder.feed(data):
            frame = xbee.parse_api_frame(frame_data)
            if isinstance(frame, xbee.TxRequest):
                self._to_host += xbee.encode(xbee.RxPacket(address, frame.data))

    def to_host(self) -> bytes:
        """Return and forget the bytes the host's XBee has for the host."""
        out, self._to_host = bytes(self._to_host), bytearray()
        return out


class PtyEmulator:
    """Serves an :class:`EmulatedRadio` on the master side of a pseudo-terminal."""

    def __init__(self, radio: EmulatedRadio) -> None:
        self.radio = radio
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.port = os.ttyname(slave)
        self._slave = slave            # kept open so the pty survives reopen cycles
        os.set_blocking(self.master, False)
        self._ms = 0.0
        self._last: float | None = None

    def pump(self, now: float) -> None:
        """Move bytes both ways and advance the boards to wall-clock ``now`` (s)."""
        while select.select([self.master], [], [], 0)[0]:
            try:
                data = os.read(self.master, 4096)
            except (BlockingIOError, OSError):
                break
            if not data:
                break
            self.radio.from_host(data)
        if self._last is not None:
            self._ms += (now - self._last) * 1000.0
            whole = int(self._ms)
            self._ms -= whole
            self.radio.advance(min(whole, 1000))
        self._last = now
        out = self.radio.to_host()
        if out:
            try:
                os.write(self.master, out)
            except (BlockingIOError, OSError):
                pass

    def close(self) -> None:
        """Close both ends of the pseudo-terminal."""
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass


def main(argv: list[str] | None = None) -> int:
    """Serve the fleet's emulated robots on a pty until interrupted."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--fleet', default=None, help='fleet YAML (default: package config)')
    parser.add_argument('--period', type=float, default=0.005, help='loop period, s')
    args = parser.parse_args(argv)
    try:
        robots = load_fleet(args.fleet, hardware=True)
        coordinator = load_coordinator(args.fleet)
    except FleetError as exc:
        print(f'robot_emulator: {exc}', file=sys.stderr)
        return 2
    emulator = PtyEmulator(EmulatedRadio.for_fleet([r.address for r in robots], coordinator))
    print(f'robot_emulator: {len(robots)} boards on {emulator.port}', flush=True)
    try:
        while True:
            emulator.pump(time.monotonic())
            time.sleep(args.period)
    except KeyboardInterrupt:
        return 0
    finally:
        emulator.close()


if __name__ == '__main__':
    sys.exit(main())
