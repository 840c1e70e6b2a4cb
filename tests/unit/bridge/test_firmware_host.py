"""The firmware's portable C (built with gcc, loaded with ctypes) against the Python side:
same frames, same decoded commands, same fixed-point mix (eqs. 5.1-5.3), 500 ms watchdog,
commands obeyed only from the coordinator's 64-bit address (the emulator filters alike)."""

from __future__ import annotations

import math
import pathlib
import re

from board_frames import board_messages, COORDINATOR
from hypothesis import given, settings
from hypothesis import strategies as st

from swarm_bridge import emulator, protocol, xbee

HOST = COORDINATOR
STRANGER = HOST ^ 0x01              # one bit away from the coordinator
HEADER = pathlib.Path(__file__).resolve().parents[3] / 'firmware/include/swarm_protocol.h'


def command_frame(message: protocol.Message, address: int = HOST) -> bytes:
    return xbee.encode(xbee.RxPacket(address, message.encode()))


def test_header_constants_equal_the_python_ones():
    text = HEADER.read_text()
    defines = dict(re.findall(r'#define SWP_(\w+)\s+(0x[0-9A-Fa-f]+|\d+)\b', text))
    modules = {'XBEE_': xbee, 'API_': xbee, 'MSG_': protocol, 'LEN_': protocol,
               'ACK_': protocol, 'FAULT_': protocol, 'DELIVERY_': xbee}
    checked = 0
    for name, value in defines.items():
        py = name.removeprefix('XBEE_')
        module = next((m for p, m in modules.items() if name.startswith(p)), protocol)
        if hasattr(module, py):
            assert getattr(module, py) == int(value, 0), name
            checked += 1
    assert checked >= 35
    table = re.search(r'SWP_SIN_Q15_TABLE \{([^}]*)\}', text).group(1)
    assert tuple(int(v) for v in re.findall(r'\d+', table)) == protocol.SIN_Q15_TABLE


def test_cmd_vel_is_decoded_mixed_applied_and_acknowledged(firmware):
    firmware.reset()
    firmware.feed(b'\x00garbage\x7e\x00' + command_frame(protocol.CmdVel(9, 300, 90)))
    assert list(firmware.rates) == list(protocol.mix_fixed(300, 90)[0])
    sent = board_messages(firmware.take_tx())
    assert sent == [(HOST, protocol.Ack(9, protocol.MSG_CMD_VEL, protocol.ACK_OK))]


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 0xFFFF), st.integers(0, 359))
def test_c_mixer_equals_python_mixer(firmware, speed, direction):
    clipped = firmware.lib.mixer_mix(speed, direction)
    rates, py_clipped = protocol.mix_fixed(speed, direction)
    assert tuple(firmware.mix_rate) == rates and bool(clipped) == py_clipped


@given(st.integers(0, 3000), st.integers(0, 359))
def test_fixed_point_mix_follows_eqs_5_1_to_5_3(speed, direction):
    rates, clipped = protocol.mix_fixed(speed, direction)
    # wheel speed rounded to 0.1 mm/s, then to whole half-steps/s: at most 1.7 steps/s
    bound = 0.5 * protocol.STEPS_PER_UNIT_Q12 / 4096 + 0.5 + 1e-3
    ideal = protocol.wheel_speeds(speed / protocol.SPEED_UNITS_PER_M_S, direction)
    for rate, v in zip(rates, ideal):
        steps = v * protocol.HALF_STEPS_PER_M
        if abs(steps) < protocol.MAX_STEP_RATE - 1:
            assert abs(rate - steps) <= bound + abs(steps) * 1e-3
        else:
            assert abs(rate) == protocol.MAX_STEP_RATE or abs(rate - steps) <= bound


@given(st.floats(-0.03, 0.03), st.floats(-0.03, 0.03), st.floats(-math.pi, math.pi))
def test_body_command_reproduces_the_map_velocity(vx, vy, yaw):
    cmd = protocol.command_for(vx, vy, yaw, 1.0, 0)
    wheels = protocol.wheel_speeds(cmd.speed / protocol.SPEED_UNITS_PER_M_S, cmd.direction)
    bx, by = protocol.body_velocity_from_wheels(wheels)
    c, s = math.cos(yaw), math.sin(yaw)
    mx, my = c * bx - s * by, s * bx + c * by
    tolerance = 1e-4 + math.hypot(vx, vy) * math.radians(0.5)
    assert math.hypot(mx - vx, my - vy) <= tolerance


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(
    st.builds(protocol.CmdVel, st.integers(0, 255), st.integers(0, 0xFFFF),
              st.integers(0, 359)).map(command_frame),
    st.builds(protocol.Stop, st.integers(0, 255)).map(command_frame),
    st.builds(protocol.Stop, st.integers(0, 255)).map(
        lambda m: command_frame(m, STRANGER)),
    st.binary(max_size=20)), max_size=8), st.data())
def test_c_parser_and_python_decoder_agree_on_any_stream(firmware, chunks, data):
    stream = bytearray(b''.join(chunks))
    for _ in range(data.draw(st.integers(0, 3))):  # random corruptions
        if stream:
            i = data.draw(st.integers(0, len(stream) - 1))
            stream[i] = data.draw(st.integers(0, 255))
    firmware.reset()
    firmware.take_tx()
    firmware.feed(bytes(stream))
    py = xbee.FrameDecoder(max_frame_data=18)   # SWP_MAX_FRAME_DATA
    frames = py.feed(bytes(stream))
    counters = firmware.parser_counters()
    assert counters['frames'] == len(frames) % 256
    assert counters['bad_checksums'] == py.stats.bad_checksums % 256
    assert counters['truncated'] == py.stats.truncated % 256
    assert counters['oversize'] == py.stats.oversize % 256
    # and the last valid command decoded by Python is the one the board applies
    commands = []
    foreign = 0
    for f in frames:
        if f[0] == xbee.API_RX_PACKET and len(f) >= xbee.RX_HEADER_LEN \
                and f[1:9] != HOST.to_bytes(8, 'big'):
            foreign += 1
        elif f[0] == xbee.API_RX_PACKET and len(f) >= xbee.RX_HEADER_LEN + 2:
            try:
                commands.append(protocol.decode_message(f[xbee.RX_HEADER_LEN:]))
            except protocol.MessageError:
                pass
    commands = [c for c in commands if isinstance(c, protocol.CmdVel | protocol.Stop)]
    expected = (0, 0, 0)
    if commands and isinstance(commands[-1], protocol.CmdVel):
        expected = protocol.mix_fixed(commands[-1].speed, commands[-1].direction)[0]
    assert tuple(firmware.rates) == expected
    assert firmware.robot.foreign == foreign % 256
    # the emulator (the HIL demo's board) filters and counts alike
    board = emulator.EmulatedBoard(1, coordinator=HOST)
    board.receive(bytes(stream))
    assert tuple(board.rates) == expected and board.foreign == foreign


def test_only_the_coordinator_commands_the_board(firmware):
    """A 0x90 frame whose source differs from the coordinator's address in any one of its
    8 bytes is dropped unanswered and counted (status byte foreign, fault FOREIGN); the
    coordinator's command is obeyed and acknowledged to the coordinator."""
    firmware.reset()
    firmware.take_tx()
    for k in range(8):
        firmware.feed(command_frame(protocol.CmdVel(k, 300, 90), HOST ^ (0x80 << 8 * k)))
    assert not any(firmware.rates) and firmware.take_tx() == b''
    assert firmware.robot.foreign == 8
    firmware.feed(command_frame(protocol.CmdVel(9, 300, 90)))
    assert tuple(firmware.rates) == protocol.mix_fixed(300, 90)[0]
    firmware.ticks(protocol.HEARTBEAT_MS)
    sent = board_messages(firmware.take_tx())
    assert sent[0] == (HOST, protocol.Ack(9, protocol.MSG_CMD_VEL, protocol.ACK_OK))
    address, status = sent[-1]
    assert address == HOST and status.foreign == 8 and status.faults & protocol.FAULT_FOREIGN
    firmware.ticks(protocol.HEARTBEAT_MS)      # the flag clears once reported, not the count
    status = board_messages(firmware.take_tx())[-1][1]
    assert status.foreign == 8 and not status.faults & protocol.FAULT_FOREIGN


def test_a_stranger_can_neither_stop_nor_keep_alive_a_robot(firmware):
    """A stranger's STOP leaves the coordinator's command running; its CmdVel every
    100 ms does not restart the watchdog, which stops the wheels 500 ms after the
    coordinator's last command."""
    firmware.reset()
    firmware.feed(command_frame(protocol.CmdVel(1, 200, 45)))
    rates = tuple(firmware.rates)
    firmware.feed(command_frame(protocol.Stop(2), STRANGER))
    assert tuple(firmware.rates) == rates and any(rates)
    for k in range(4):
        firmware.ticks(100)
        firmware.feed(command_frame(protocol.CmdVel(3 + k, 200, 45), STRANGER))
    firmware.ticks(protocol.CMD_TIMEOUT_MS - 400 - 1)
    assert tuple(firmware.rates) == rates
    firmware.ticks(1)
    assert not any(firmware.rates) and firmware.robot.foreign == 5


def test_statuses_go_to_the_coordinator_from_power_up(firmware):
    firmware.reset()
    firmware.take_tx()
    firmware.ticks(protocol.HEARTBEAT_MS)
    sent = board_messages(firmware.take_tx())
    assert [a for a, _ in sent] == [HOST]
    assert isinstance(sent[0][1], protocol.Status) and len(sent[0][1].encode()) == 14


def test_watchdog_stops_the_motors_500_ms_after_the_last_command(firmware):
    firmware.reset()
    firmware.feed(command_frame(protocol.CmdVel(1, 200, 45)))
    firmware.ticks(protocol.CMD_TIMEOUT_MS - 1)
    assert any(firmware.rates) and any(firmware.coils)
    firmware.ticks(1)
    assert not any(firmware.rates) and not any(firmware.coils)
    firmware.take_tx()
    firmware.ticks(protocol.HEARTBEAT_MS)
    status = [m for _, m in board_messages(firmware.take_tx())
              if isinstance(m, protocol.Status)][-1]
    assert status.faults & protocol.FAULT_WATCHDOG and status.rates == (0, 0, 0)
    # a new command clears the watchdog fault and moves again
    firmware.feed(command_frame(protocol.CmdVel(2, 200, 45)))
    assert any(firmware.rates)


def test_steps_follow_the_rates_and_heartbeats_report_them(firmware):
    firmware.reset()
    firmware.take_tx()
    cmd = protocol.CmdVel(3, 250, 200)
    rates = protocol.mix_fixed(cmd.speed, cmd.direction)[0]
    for _ in range(4):  # keep the command fresh for 1 s
        firmware.feed(command_frame(cmd))
        firmware.ticks(250)
    assert tuple(firmware.positions) == tuple(rates)  # 1 s at r half-steps/s: r steps
    statuses = [m for _, m in board_messages(firmware.take_tx())
                if isinstance(m, protocol.Status)]
    assert len(statuses) == 1000 // protocol.HEARTBEAT_MS
    assert statuses[0].faults & protocol.FAULT_RESET
    assert statuses[-1].rates == rates and statuses[-1].last_cmd_seq == 3


def test_bad_messages_are_refused_with_a_reason(firmware):
    firmware.reset()
    firmware.take_tx()
    firmware.feed(xbee.encode(xbee.RxPacket(HOST, b'\x01\x05\x00')))            # short
    firmware.feed(xbee.encode(xbee.RxPacket(HOST, b'\x01\x06\x00\x10\x01\x68')))  # 360 deg
    firmware.feed(xbee.encode(xbee.RxPacket(HOST, b'\x42\x07')))                 # unknown
    acks = [m for _, m in board_messages(firmware.take_tx())]
    assert [a.result for a in acks] == [protocol.ACK_BAD_LENGTH, protocol.ACK_BAD_VALUE,
                                        protocol.ACK_UNKNOWN_TYPE]
    assert not any(firmware.rates)


def test_frames_are_parsed_in_the_interrupt_and_handed_over_through_a_mailbox(firmware):
    """The receive interrupt parses; the main loop takes one frame at a time. A frame
    finished while the main loop has not taken the previous one is dropped, counted as
    busy and reported as a bad frame; the next one after the hand-over is applied."""
    firmware.reset()
    firmware.take_tx()
    first = command_frame(protocol.CmdVel(1, 200, 45))
    second = command_frame(protocol.CmdVel(2, 300, 90))
    firmware.feed_isr(first)
    assert firmware.mailbox_full() and not any(firmware.rates)   # main loop not yet run
    firmware.feed_isr(second)                                     # mailbox still full
    assert firmware.parser_counters()['busy'] == 1
    firmware.poll()
    assert not firmware.mailbox_full()
    assert tuple(firmware.rates) == protocol.mix_fixed(200, 45)[0]
    acks = [m for _, m in board_messages(firmware.take_tx()) if isinstance(m, protocol.Ack)]
    assert [(a.seq, a.result) for a in acks] == [(1, protocol.ACK_OK)]
    firmware.feed_isr(second)
    firmware.poll()
    assert tuple(firmware.rates) == protocol.mix_fixed(300, 90)[0]
    firmware.ticks(protocol.HEARTBEAT_MS)
    status = [m for _, m in board_messages(firmware.take_tx()) if isinstance(m, protocol.Status)]
    assert status and status[-1].faults & protocol.FAULT_BAD_FRAME and status[-1].bad_frames == 1


def test_a_long_length_is_dropped_at_its_high_byte_by_both(firmware):
    """Found by the stream test: a start, a high length byte of 1 (over the 18-byte
    limit), then a whole frame. Both parsers drop the first frame as oversize at its
    high byte (not truncated by the next start) and take the second."""
    stream = b'~\x01' + command_frame(protocol.CmdVel(0, 0, 0))
    firmware.reset()
    firmware.feed(stream)
    py = xbee.FrameDecoder(max_frame_data=18)
    assert len(py.feed(stream)) == 1
    counters = firmware.parser_counters()
    assert (counters['frames'], counters['oversize'], counters['truncated']) == (1, 1, 0)
    assert (py.stats.frames, py.stats.oversize, py.stats.truncated) == (1, 1, 0)
