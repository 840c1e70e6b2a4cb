"""The firmware built for the real chip with sdcc (pic14 port) and gputils."""

from __future__ import annotations

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
