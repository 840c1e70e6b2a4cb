#!/usr/bin/env python3
"""Print flash (words) and RAM (bytes) use of the PIC build from gplink's map file.

usage: memory_report.py MAP FLASH_WORDS RAM_BYTES
"""

import re
import sys


def main() -> int:
    """Sum the ROM and RAM sections of a gplink map and compare them with the chip."""
    path, flash_total, ram_total = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    text = open(path).read()
    flash = ram = 0
    # Section table rows: name  type  address  location  size(hex, bytes)
    for name, _kind, _addr, location, size in re.findall(
            r'^\s*(\S+)\s+(code|udata|idata|udata_ovr|udata_acs|udata_shr|data)\s+'
            r'(0x[0-9a-f]+)\s+(program|data)\s+(0x[0-9a-f]+)', text, re.M | re.I):
        n = int(size, 16)
        if location.lower() == 'data' and int(_addr, 16) & 0x7F < 0x20:
            continue  # special function registers declared by address (__sfr __at): no RAM
        if location.lower() == 'program':
            if name.lower() not in ('config', 'config_word', '__config_0x2007'):
                flash += n // 2
        else:
            ram += n
    print(f'flash: {flash} of {flash_total} words ({100.0 * flash / flash_total:.1f} %)')
    print(f'RAM:   {ram} of {ram_total} bytes ({100.0 * ram / ram_total:.1f} %; general '
          'purpose registers only, SFRs excluded)')
    return 0 if flash <= flash_total and ram <= ram_total else 1


if __name__ == '__main__':
    sys.exit(main())
