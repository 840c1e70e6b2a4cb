"""The firmware built for the PIC16F690 runs in gpsim and agrees with the Python emulator.

One gpsim run (1.3 s of chip time, 8 MHz): gpsim's usart module is wired to the EUSART
(its TX to RB5/RX, its RX to RB7/TX) and types XBee API frames at 9600 baud; writes to
PORTA/PORTC (the three ULN2003 channels) are logged. The same frames go to
swarm_bridge.emulator.EmulatedBoard at the millisecond their last byte arrives. Checked:
the bytes the board sends (acks, statuses every 200 ms) decode to the emulator's messages
(cmd_age_ms to the chip's command latency); the coils start after the command and go
quiet 500 ms after it (watchdog); frames from another XBee than the coordinator (a STOP
that would stop the wheels early, a CmdVel that would keep them running) are ignored,
unanswered and counted; a frame with a bad checksum is not acknowledged and is counted;
each motor channel half-steps in the emulator's direction as often as the emulator's wheel
(eqs. 5.1-5.3 mix). This last check found the interrupt overwriting sdcc's STK00 under
the main loop's table read (wheel B at 187 instead of 337 half-steps/s; see PROTOCOL.md,
"Interrupt rule").
"""

from __future__ import annotations

import math
import re
import subprocess

from board_frames import board_messages, COORDINATOR
import pic_toolchain
import pytest

from swarm_bridge import emulator, protocol, xbee

pytestmark = pytest.mark.skipif(pic_toolchain.missing(gpsim=True) is not None,
                                reason=str(pic_toolchain.missing(gpsim=True)))

HOST = COORDINATOR
STRANGER = 0x0013A20041FFFF02        # another XBee in range
CYCLES_PER_MS = 2000                 # 8 MHz / 4
BYTE_MS = 10 * 1000 / 9600           # start + 8 data + stop bits
HALF_STEP = [0x01, 0x03, 0x02, 0x06, 0x04, 0x0C, 0x08, 0x09]
END_MS = 1300
LATENCY_MS = 15                      # command applied after its last byte, at most


def frame(message: protocol.Message, corrupt: bool = False, source: int = HOST) -> bytes:
    data = bytearray(xbee.encode(xbee.RxPacket(source, message.encode())))
    if corrupt:
        data[-1] ^= 0x01              # the checksum (never an escaped byte here)
    return bytes(data)


INPUT = [(250, frame(protocol.CmdVel(9, 300, 90))),
         (400, frame(protocol.Stop(20), source=STRANGER)),
         (600, frame(protocol.CmdVel(21, 300, 270), source=STRANGER)),
         (850, frame(protocol.CmdVel(10, 300, 90), corrupt=True))]


@pytest.fixture(scope='module')
def pic_build(tmp_path_factory):
    """The PIC build's directory: swarm_robot.cod and sdcc's .asm of every source."""
    out = tmp_path_factory.mktemp('gpsim')
    build = subprocess.run(['make', '-C', str(pic_toolchain.FIRMWARE), 'pic',
                            f'PIC_DIR={out}', f'COORDINATOR={HOST:016X}'],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stdout + build.stderr
    return out


@pytest.fixture(scope='module')
def gpsim_run(pic_build):
    out = pic_build
    log = out / 'ports.log'
    lines = [f'load s {out}/swarm_robot.cod', 'p16f690.frequency = 8000000',
             'module library libgpsim_modules', 'module load usart U1',
             'U1.rxbaud = 9600', 'U1.txbaud = 9600', 'node n_rx', 'attach n_rx U1.TXPIN portb5',
             'node n_tx', 'attach n_tx U1.RXPIN portb7', 'U1.console = true', 'U1.hex = true',
             f'log on {log}', 'log w portc', 'log w porta']
    for at_ms, data in INPUT:
        lines += [f'break c {at_ms * CYCLES_PER_MS}', 'run']
        lines += [f'U1.tx = 0x{b:02x}' for b in data]
    lines += [f'break c {END_MS * CYCLES_PER_MS}', 'run', 'quit']
    script = out / 'run.stc'
    script.write_text('\n'.join(lines) + '\n')
    result = subprocess.run(['gpsim', '-i', '-c', str(script)], capture_output=True,
                            timeout=300)
    text = result.stdout.decode('latin-1')
    assert 'invalid file register' not in text and 'stack' not in text.lower(), text[-2000:]
    sent = bytes(int(h, 16) for h in re.findall(r'<([0-9A-F]{2})>', text))
    writes, cycle = [], 0
    for line in log.read_text(errors='replace').splitlines():
        if m := re.match(r'0x([0-9A-F]{16}) ', line):
            cycle = int(m.group(1), 16)
        elif m := re.search(r'Wrote: 0x([0-9A-F]{4}) to port([ac])', line):
            writes.append((cycle / CYCLES_PER_MS, m.group(2), int(m.group(1), 16)))
    return sent, writes


@pytest.fixture(scope='module')
def emulated():
    board = emulator.EmulatedBoard(0, coordinator=HOST)
    done = {math.ceil(at + len(data) * BYTE_MS): data for at, data in INPUT}
    sent = bytearray()
    for ms in range(1, END_MS + 1):
        board.tick(1)
        if ms in done:
            board.receive(done[ms])
        sent += board.transmit()
    return board, bytes(sent)


def channel_patterns(writes) -> list[list[tuple[float, int]]]:
    """Per motor channel: (ms, coil pattern) at every change."""
    porta = portc = 0
    out: list[list[tuple[float, int]]] = [[(0.0, 0)], [(0.0, 0)], [(0.0, 0)]]
    for ms, port, value in writes:
        if port == 'a':
            porta = value
        else:
            portc = value
        for ch, pattern in enumerate((portc & 0x0F, portc >> 4,
                                      (porta & 0x07) | ((porta >> 1) & 0x08))):
            if pattern != out[ch][-1][1]:
                out[ch].append((ms, pattern))
    return out


def test_board_sends_what_the_emulator_sends(gpsim_run, emulated):
    """Same messages; wheel rates are checked below, cmd_age_ms to the chip's latency."""
    chip, emu = board_messages(gpsim_run[0]), board_messages(emulated[1])
    assert [type(m).__name__ for _, m in chip] == [type(m).__name__ for _, m in emu]
    assert len([m for _, m in chip if isinstance(m, protocol.Status)]) == 6
    for (a_chip, m_chip), (a_emu, m_emu) in zip(chip, emu):
        assert a_chip == a_emu
        if isinstance(m_chip, protocol.Status):
            # the PIC applies a command ~8 ms after its last byte (mixing in software
            # while the 1 kHz tick takes most of the CPU); the emulator at once
            assert -LATENCY_MS <= m_chip.cmd_age_ms - m_emu.cmd_age_ms <= 0 or \
                m_emu.cmd_age_ms == 0xFFFF, (m_chip, m_emu)
            m_chip = protocol.Status(m_chip.seq, m_chip.last_cmd_seq, m_emu.cmd_age_ms,
                                     m_emu.rates, m_chip.faults, m_chip.bad_frames,
                                     m_chip.foreign)
        assert m_chip == m_emu
    acks = [m for _, m in chip if isinstance(m, protocol.Ack)]
    assert acks == [protocol.Ack(9, protocol.MSG_CMD_VEL, protocol.ACK_OK)]  # not 20, 21, 10
    assert {a for a, _ in chip} == {HOST}
    statuses = [m for _, m in chip if isinstance(m, protocol.Status)]
    assert [s.foreign for s in statuses] == [0, 0, 1, 2, 2, 2]   # at 200, 400, ... 1200 ms
    assert [bool(s.faults & protocol.FAULT_FOREIGN) for s in statuses] == [
        False, False, True, True, False, False]
    assert statuses[-1].bad_frames == 1


def test_watchdog_stops_the_coils_500_ms_after_the_command(gpsim_run):
    command_done = INPUT[0][0] + len(INPUT[0][1]) * BYTE_MS
    for ch, changes in enumerate(channel_patterns(gpsim_run[1])):
        active = [(ms, p) for ms, p in changes if p]
        assert active and command_done < active[0][0] <= command_done + LATENCY_MS, ch
        stop = next(ms for ms, p in changes if ms > active[0][0] and p == 0)
        late = stop - (command_done + protocol.CMD_TIMEOUT_MS)
        assert 0 <= late <= LATENCY_MS, (ch, stop)
        assert changes[-1][1] == 0


def test_wheels_step_at_the_mixed_rates(gpsim_run, emulated):
    rates, _ = protocol.mix_fixed(300, 90)
    board, sent = emulated
    statuses = [m for _, m in board_messages(gpsim_run[0]) if isinstance(m, protocol.Status)]
    assert statuses[1].rates == rates
    for ch, changes in enumerate(channel_patterns(gpsim_run[1])):
        phases = [HALF_STEP.index(p) for _, p in changes if p]
        steps = [(b - a) % 8 for a, b in zip(phases, phases[1:])]
        assert steps and set(steps) == {1 if rates[ch] > 0 else 7}, (ch, steps[:10])
        # the first pattern is phase 0, energised before the first step; both count the
        # same 500 ticks with the same accumulator, so at most a tick's alignment apart
        assert abs(len(steps) - abs(board.positions[ch])) <= 1, (ch, len(steps))


def asm_functions(out) -> dict[str, list[str]]:
    """Instructions (comments dropped) of every function in sdcc's .asm files, by label."""
    functions: dict[str, list[str]] = {}
    body: list[str] = []
    for path in sorted(out.glob('*.asm')):
        for line in path.read_text().splitlines():
            if m := re.match(r'(_[A-Za-z]\w*):', line):   # not local labels (_00123_DS_)
                body = functions.setdefault(m.group(1), [])
            elif (code := line.split(';')[0].strip()) and line[0] in ' \t':
                body.append(code)
    return functions


def test_interrupt_leaves_the_stk_registers_alone(pic_build):
    """sdcc's pic14 interrupt saves W, STATUS, PCLATH and FSR, not STK00..: whatever it
    calls passes and returns one byte at most (in W) and calls no library routine (they
    keep state in STK00..). A two-byte hal_coils(ch, pattern) once broke wheel B's mix."""
    functions = asm_functions(pic_build)
    todo, seen = ['_isr'], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        assert name in functions and not name.startswith('__'), \
            f'the interrupt reaches the library routine {name}'
        for code in functions[name]:
            assert not re.search(r'\bSTK\d\d\b', code), (name, code)
            if m := re.match(r'CALL\s+(\w+)', code, re.IGNORECASE):
                todo.append(m.group(1))
    assert {'_robot_tick', '_stepper_tick', '_hal_coils', '_xp_feed'} <= seen
