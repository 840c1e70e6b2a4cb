"""The firmware built for the real chip with sdcc (pic14 port) and gputils."""

from __future__ import annotations

import hashlib
import re
import subprocess

import pic_toolchain
import pytest


@pytest.mark.skipif(pic_toolchain.missing() is not None,
                    reason=str(pic_toolchain.missing()))
def test_pic_build_fits_the_chip(tmp_path):
    result = subprocess.run(['make', '-C', str(pic_toolchain.FIRMWARE), 'pic',
                             f'PIC_DIR={tmp_path}'], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    flash = re.search(r'flash: (\d+) of 4096 words', result.stdout)
    ram = re.search(r'RAM:\s+(\d+) of 256 bytes', result.stdout)
    assert flash and ram, result.stdout
    assert int(flash.group(1)) <= 4096 and int(ram.group(1)) <= 256
    assert (tmp_path / 'swarm_robot.hex').stat().st_size > 0


def memory(output: str) -> tuple[int, int]:
    """(flash words, RAM bytes) from tools/memory_report.py's lines."""
    flash = re.search(r'flash: (\d+) of 4096 words', output)
    ram = re.search(r'RAM:\s+(\d+) of 256 bytes', output)
    assert flash and ram, output
    return int(flash.group(1)), int(ram.group(1))


@pytest.mark.skipif(pic_toolchain.missing(gpsim=True) is not None,
                    reason=str(pic_toolchain.missing(gpsim=True)))
def test_one_sha256_block_does_not_fit_beside_the_firmware(tmp_path_factory):
    """tools/sha256_probe.c: one SHA-256 compression, built alone for the chip, computes
    the FIPS 180-4 digest of "abc" in gpsim, and needs more flash and RAM than the
    firmware leaves free (docs/security.md, "What the PIC16F690 cannot afford")."""
    # a short directory: gpsim silently loads nothing from a .cod whose recorded source
    # paths are long (pytest's per-test directory name was)
    tmp_path = tmp_path_factory.mktemp('sha')
    make = ['make', '-C', str(pic_toolchain.FIRMWARE)]
    firmware = subprocess.run(make + ['pic', f'PIC_DIR={tmp_path / "fw"}'],
                              capture_output=True, text=True)
    probe = subprocess.run(make + ['sha256-probe', f'PROBE_DIR={tmp_path}'],
                           capture_output=True, text=True)
    assert firmware.returncode == 0 and probe.returncode == 0, probe.stdout + probe.stderr
    (fw_flash, fw_ram), (sha_flash, sha_ram) = memory(firmware.stdout), memory(probe.stdout)
    log = tmp_path / 'porta.log'
    script = tmp_path / 'run.stc'
    script.write_text(f'load s {tmp_path}/sha256_probe.cod\np16f690.frequency = 8000000\n'
                      f'log on {log}\nlog w porta\nbreak c 2000000\nrun\ndump r\nquit\n')
    out = subprocess.run(['gpsim', '-i', '-c', str(script)], capture_output=True,
                         timeout=120).stdout.decode('latin-1')
    ram = {}
    for row, octets in re.findall(r'^([0-9a-f]{4}):  ((?:[0-9a-f-]{2} ){16})', out, re.M):
        for k, octet in enumerate(octets.split()):
            ram[int(row, 16) + k] = octet
    at = int(re.search(r'\b_H\s+0x([0-9a-f]+)\s+data', (tmp_path / 'sha256_probe.map')
                       .read_text()).group(1), 16)
    digest = bytes.fromhex(''.join(''.join(ram[at + 4 * w + i] for i in (3, 2, 1, 0))
                                   for w in range(8)))
    assert digest == hashlib.sha256(b'abc').digest()
    cycles = [int(c, 16) for c in re.findall(r'^0x([0-9A-F]{16}) ', log.read_text(), re.M)]
    block_ms = (cycles[1] - cycles[0]) / 2000.0          # 2 M instruction cycles per s
    print(f'firmware {fw_flash} words {fw_ram} bytes; one SHA-256 block {sha_flash} words '
          f'{sha_ram} bytes, {cycles[1] - cycles[0]} cycles = {block_ms:.0f} ms at 8 MHz')
    assert sha_flash > 4096 - fw_flash and sha_ram > 256 - fw_ram
    assert block_ms > 100.0        # the 100 ms command period of bridge.yaml's resend_period
