"""Fixtures of the bridge tests: the firmware's portable C built for the host."""

from __future__ import annotations

import ctypes
import pathlib
import re
import shutil
import subprocess

from board_frames import COORDINATOR
import pytest

FIRMWARE = pathlib.Path(__file__).resolve().parents[3] / 'firmware'


class RobotState(ctypes.Structure):
    """robot_t of firmware/src/robot.h, up to the coordinator address."""

    _fields_ = [('cmd_age_ms', ctypes.c_uint16), ('heartbeat_ms', ctypes.c_uint16),
                ('heartbeat_due', ctypes.c_uint8), ('faults', ctypes.c_uint8),
                ('status_seq', ctypes.c_uint8), ('last_cmd_seq', ctypes.c_uint8),
                ('running', ctypes.c_uint8), ('foreign', ctypes.c_uint8),
                ('host', ctypes.c_uint8 * 8)]


class Firmware:
    """The firmware library (build/host/libswarmfw.so) driven through ctypes."""

    def __init__(self, path: pathlib.Path) -> None:
        self.lib = ctypes.CDLL(str(path))
        self.lib.fw_feed.argtypes = [ctypes.c_char_p, ctypes.c_uint32]
        self.lib.fw_ticks.argtypes = [ctypes.c_uint32]
        self.lib.mixer_mix.argtypes = [ctypes.c_uint16, ctypes.c_uint16]
        self.lib.mixer_mix.restype = ctypes.c_uint8
        self.rates = (ctypes.c_int16 * 3).in_dll(self.lib, 'st_rate')
        self.mix_rate = (ctypes.c_int16 * 3).in_dll(self.lib, 'mix_rate')
        self.positions = (ctypes.c_int32 * 3).in_dll(self.lib, 'st_position')
        self.coils = (ctypes.c_uint8 * 3).in_dll(self.lib, 'host_coils')
        self.tx = (ctypes.c_uint8 * 8192).in_dll(self.lib, 'host_tx')
        self.tx_len = ctypes.c_uint32.in_dll(self.lib, 'host_tx_len')
        self.lib.fw_feed_isr.argtypes = [ctypes.c_char_p, ctypes.c_uint32]
        # xbee_parser_t: frames bad_checksums truncated oversize garbage busy state escaped
        # length index sum ready buf[...] (counters first, xbee_parser.h)
        self.parser = (ctypes.c_uint8 * 12).in_dll(self.lib, 'xp')
        self.robot = RobotState.in_dll(self.lib, 'robot')

    def reset(self) -> None:
        """Power-up state."""
        self.lib.fw_reset()

    def feed(self, data: bytes) -> None:
        """Bytes on the board's UART."""
        self.lib.fw_feed(bytes(data), len(data))

    def feed_isr(self, data: bytes) -> None:
        """Bytes through the receive interrupt only (the main loop does not run)."""
        self.lib.fw_feed_isr(bytes(data), len(data))

    def poll(self) -> None:
        """One main-loop pass: empties the mailbox, sends a due heartbeat."""
        self.lib.robot_poll()

    def ticks(self, n: int) -> None:
        """n timer ticks of 1 ms, each followed by a main-loop poll."""
        self.lib.fw_ticks(n)

    def take_tx(self) -> bytes:
        """Bytes the board sent since the last call."""
        out = bytes(self.tx[:self.tx_len.value])
        self.lib.fw_clear_tx()
        return out

    def parser_counters(self) -> dict[str, int]:
        """The C parser's counters (modulo 256)."""
        names = ('frames', 'bad_checksums', 'truncated', 'oversize', 'garbage', 'busy')
        return {n: self.parser[i] for i, n in enumerate(names)}

    def mailbox_full(self) -> bool:
        """Whether the parser's mailbox holds a frame the main loop has not taken."""
        return bool(self.parser[11])


@pytest.fixture(scope='session')
def firmware(tmp_path_factory) -> Firmware:
    """Build the firmware's host target with its Makefile (gcc) and load it."""
    if shutil.which('make') is None or shutil.which('gcc') is None:
        pytest.skip('make and gcc are needed to build the firmware for the host '
                    '(apt-get install build-essential)')
    out = tmp_path_factory.mktemp('fw_host')
    result = subprocess.run(['make', '-C', str(FIRMWARE), 'host', f'HOST_DIR={out}',
                             f'COORDINATOR={COORDINATOR:016X}'], capture_output=True, text=True)
    assert result.returncode == 0, f'make host failed:\n{result.stdout}\n{result.stderr}'
    passed = re.search(r'selftest: (\d+) of (\d+) checks passed', result.stdout)
    assert passed and passed.group(1) == passed.group(2) and int(passed.group(2)) >= 10, \
        result.stdout
    fw = Firmware(out / 'libswarmfw.so')
    fw.reset()
    return fw
