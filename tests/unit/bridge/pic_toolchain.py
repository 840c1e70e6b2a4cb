"""Where the PIC toolchain of `make toolchain` is: the same lookup as firmware/Makefile."""

from __future__ import annotations

import functools
import os
import pathlib
import shutil
import subprocess

FIRMWARE = pathlib.Path(__file__).resolve().parents[3] / 'firmware'
DEVICE_LIB = 'share/sdcc/non-free/lib/pic14/pic16f690.lib'


def prefix() -> pathlib.Path:
    """The cache prefix scripts/install_pic_toolchain.sh installs sdcc (pic14) into."""
    if os.environ.get('SWARM_SDCC_PIC_PREFIX'):
        return pathlib.Path(os.environ['SWARM_SDCC_PIC_PREFIX'])
    cache = os.environ.get('XDG_CACHE_HOME') or os.path.expanduser('~/.cache')
    return pathlib.Path(cache) / 'swarm-formation' / 'sdcc-pic'


def sdcc() -> str | None:
    """The sdcc firmware/Makefile uses: the cached one, else the one on PATH."""
    cached = prefix() / 'bin' / 'sdcc'
    return str(cached) if cached.exists() else shutil.which('sdcc')


@functools.cache
def missing(gpsim: bool = False) -> str | None:
    """None when the firmware can be built (and simulated); else a one-line skip reason."""
    path = sdcc()
    if path is None or shutil.which('gplink') is None:
        what = 'sdcc (pic14) and gputils'
    elif 'pic14' not in subprocess.run([path, '--version'], capture_output=True,
                                       text=True).stdout:
        what = f'sdcc with the pic14 port ({path} has none)'
    elif not (pathlib.Path(path).parents[1] / DEVICE_LIB).exists():
        what = f'the pic16f690 device library next to {path}'
    elif gpsim and shutil.which('gpsim') is None:
        what = 'gpsim'
    else:
        return None
    return f'needs {what}: run make toolchain'
