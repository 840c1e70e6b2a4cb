"""The firmware built for the real chip with sdcc (pic14 port) and gputils."""

from __future__ import annotations

import pathlib
import shutil
import subprocess

import pytest

FIRMWARE = pathlib.Path(__file__).resolve().parents[3] / 'firmware'


def _sdcc_has_pic14() -> bool:
    if shutil.which('sdcc') is None or shutil.which('gplink') is None:
        return False
    out = subprocess.run(['sdcc', '--version'], capture_output=True, text=True).stdout
    return 'pic14' in out


@pytest.mark.skipif(not _sdcc_has_pic14(), reason='needs sdcc with the pic14 port and '
                    'gputils; Debian builds sdcc without pic14 (see firmware/PROTOCOL.md)')
def test_pic_build_fits_the_chip(tmp_path):
    result = subprocess.run(['make', '-C', str(FIRMWARE), 'pic', f'PIC_DIR={tmp_path}'],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'flash:' in result.stdout and 'RAM:' in result.stdout
